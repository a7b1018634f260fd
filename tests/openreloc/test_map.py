"""ObjectMap save/load: round trip, compactness, determinism, checksum and version errors."""

from __future__ import annotations

import json
from pathlib import Path

import networkx as nx
import numpy as np
import pytest

from openreloc_bench.data.mapfile import MANIFEST
from openreloc_bench.errors import DataError
from openreloc_bench.openreloc.anchors import Anchors, DescriptorCodec
from openreloc_bench.openreloc.map import (
    COMPONENTS,
    Landmark,
    ObjectMap,
    ReferenceFrame,
    map_size_bytes,
)
from openreloc_bench.vision.local_features import root_sift


def make_map(n: int = 5, dim: int = 16, seed: int = 0) -> ObjectMap:
    rng = np.random.default_rng(seed)
    landmarks = {}
    for i in range(1, n + 1):
        pts = (rng.uniform(0, 1, (50, 3)) + [i, 0, 0]).astype(np.float32)
        d = rng.normal(size=dim).astype(np.float32)
        landmarks[i] = Landmark(
            id=i,
            points=pts,
            box_min=pts.min(0),
            box_max=pts.max(0),
            center=pts.mean(0),
            descriptor=d / np.linalg.norm(d),
            valid=i != n,
            category="wall" if i == n else f"cat{i}",
            n_views=i,
        )
    T = np.eye(4)
    T[:3, 3] = [1, 2, 3]
    rfs = [
        ReferenceFrame(0, np.eye(4), {1: np.array([1, 2, 30, 40], np.float32)}, {1: 0.5}),
        ReferenceFrame(
            7, T, {2: np.array([0, 0, 5, 5], np.float32), 3: np.array([5, 6, 7, 8], np.float32)}, {2: 1.0, 3: 0.25}
        ),
    ]
    g = nx.Graph()
    g.add_nodes_from(landmarks)
    g.add_edge(1, 2, kind="knn")
    g.add_edge(3, 2, kind="overlap")
    K = np.array([[100.0, 0, 31.5], [0, 100, 23.5], [0, 0, 1]])
    root = root_sift(rng.integers(0, 255, (7, 128)).astype(np.uint8))
    codec, codes = DescriptorCodec.fit(root, 4)
    anchors = Anchors(
        rng.uniform(0, 5, (7, 3)).astype(np.float32),
        codes,
        np.array([1, 1, 2, 2, 2, 3, 4], np.int32),
        codec,
    )
    up = np.array([0.0, -1.0, 0.0])  # a recording's world: gravity along +y
    return ObjectMap(landmarks, rfs, g, K, 64, 48, {"name": "test"}, {"voxel": 0.02}, {"frames_total": 9}, anchors, up)


def test_round_trip(tmp_path: Path) -> None:
    m = make_map()
    m.save(tmp_path / "m")
    r = ObjectMap.load(tmp_path / "m")
    assert sorted(r.landmarks) == sorted(m.landmarks)
    for i, lm in m.landmarks.items():
        got = r.landmarks[i]
        assert np.abs(got.points - lm.points).max() <= 0.0006  # 1 mm quantisation
        np.testing.assert_allclose(got.box_min, lm.box_min, atol=1e-6)
        np.testing.assert_allclose(got.center, lm.center, atol=1e-6)
        np.testing.assert_allclose(got.descriptor, lm.descriptor, atol=2e-3)  # float16
        assert (got.valid, got.category, got.n_views) == (lm.valid, lm.category, lm.n_views)
    assert r.valid_ids() == [1, 2, 3, 4]
    assert r.descriptor_matrix([2, 1]).shape == (2, 16)
    assert r.descriptor_matrix([2, 1]).dtype == np.float32
    assert [rf.index for rf in r.reference_frames] == [0, 7]
    np.testing.assert_allclose(r.reference_frames[1].T_wc, m.reference_frames[1].T_wc)
    assert r.reference_frames[1].boxes.keys() == {2, 3}
    np.testing.assert_allclose(r.reference_frames[1].boxes[3], [5, 6, 7, 8])
    assert r.reference_frames[1].visibility[3] == pytest.approx(0.25)
    assert {(min(u, v), max(u, v), d["kind"]) for u, v, d in r.graph.edges(data=True)} == {
        (1, 2, "knn"),
        (2, 3, "overlap"),
    }
    assert set(r.graph.nodes) == set(m.landmarks)
    for part in ("xyz", "codes", "landmark"):
        np.testing.assert_array_equal(getattr(r.anchors, part), getattr(m.anchors, part))
    np.testing.assert_array_equal(r.anchors.codec.centroids, m.anchors.codec.centroids)
    np.testing.assert_array_equal(r.up, m.up)
    assert (r.width, r.height, r.encoder, r.config, r.stats["frames_total"]) == (
        64,
        48,
        {"name": "test"},
        {"voxel": 0.02},
        9,
    )
    a = m.anchors  # the size of each part is recorded: the keypoints' share of the map, for one
    codebook = 4 * 256 * 32 * 4  # 4 parts of 32 dimensions, 256 float32 centroids each
    assert r.stats["bytes"]["anchors"] == len(a.xyz) * (12 + 4 + 4) + codebook
    assert set(r.stats["bytes"]) == set(COMPONENTS)


def test_save_is_deterministic_and_compact(tmp_path: Path) -> None:
    make_map().save(tmp_path / "a")
    make_map().save(tmp_path / "b")
    for name in ("arrays.npz", "meta.json", MANIFEST):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    big = make_map(n=200, dim=384)
    big.save(tmp_path / "big")
    # 200 landmarks x (50 points x 6 B + 384 x 2 B) + overhead: well under 1 MB
    assert map_size_bytes(tmp_path / "big") < 400_000


@pytest.mark.parametrize("damage", ["truncate", "flip"])
@pytest.mark.parametrize("name", ["arrays.npz", "meta.json"])
def test_tampered_file_is_named(tmp_path: Path, damage: str, name: str) -> None:
    make_map().save(tmp_path)
    p = tmp_path / name
    data = bytearray(p.read_bytes())
    if damage == "truncate":
        data = data[: len(data) // 2]
    else:
        data[len(data) // 2] ^= 0xFF
    p.write_bytes(bytes(data))
    with pytest.raises(DataError, match="checksum") as e:
        ObjectMap.load(tmp_path)
    assert e.value.path == p


def test_other_version_is_refused(tmp_path: Path) -> None:
    make_map().save(tmp_path)
    man = json.loads((tmp_path / MANIFEST).read_text())
    man["version"] = 99
    (tmp_path / MANIFEST).write_text(json.dumps(man))
    with pytest.raises(DataError, match="version 99") as e:
        ObjectMap.load(tmp_path)
    assert e.value.path.name == MANIFEST


def test_missing_map(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="missing: no openreloc-map here"):
        ObjectMap.load(tmp_path)
