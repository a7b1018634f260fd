import json

import numpy as np
import pytest

from baselines.goreloc.build import GORelocMappingConfig, build_goreloc_map
from baselines.goreloc.map import GORelocMap
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import DataError
from tests.baselines.goreloc.ellipsoid_world import BLOBS, write_ellipsoid_world


@pytest.fixture(scope="module")
def world_map(tmp_path_factory):
    root = write_ellipsoid_world(tmp_path_factory.mktemp("goreloc") / "world")
    return build_goreloc_map(Scene(root).sequence("mapping"), GORelocMappingConfig(), progress=False)


def test_map_holds_one_fitted_ellipsoid_per_visible_coco_object(world_map):
    blobs = {b.id: b for b in BLOBS}
    assert world_map.ids.tolist() == [b.id for b in BLOBS if b.category != "cabinet"]  # cabinet: not COCO
    for i, c, ax in zip(world_map.ids, world_map.centres, world_map.axes):
        assert np.linalg.norm(c - blobs[i].centre) < 0.1  # fitted to the surfaces the cameras saw
        assert np.allclose(np.sort(ax), np.sort(blobs[i].axes), atol=0.1)
    assert (world_map.label_counts.sum(1) >= 2).all() and (world_map.label_counts > 0).sum(1).max() == 1
    adj = world_map.adjacency()
    assert (adj == adj.T).all() and (adj.sum(1) >= 3).all()
    assert world_map.stats["instances_from"] == "masks"


def test_map_round_trip_and_corruption_errors(world_map, tmp_path):
    world_map.save(tmp_path / "m")
    back = GORelocMap.load(tmp_path / "m")
    for key in ("ids", "centres", "rotations", "axes", "label_counts", "edges"):
        assert np.array_equal(getattr(back, key), getattr(world_map, key))
    assert back.instance_labels == world_map.instance_labels and back.categories == world_map.categories
    arrays = tmp_path / "m" / "arrays.npz"
    data = bytearray(arrays.read_bytes())
    data[len(data) // 2] ^= 0xFF
    arrays.write_bytes(bytes(data))
    with pytest.raises(DataError, match="checksum") as e:
        GORelocMap.load(tmp_path / "m")
    assert "\n" not in str(e.value) and "arrays.npz" in str(e.value)


def test_map_of_another_format_version_is_refused(world_map, tmp_path):
    world_map.save(tmp_path / "m")
    manifest = tmp_path / "m" / "manifest.json"
    doc = json.loads(manifest.read_text())
    doc["version"] = 99
    manifest.write_text(json.dumps(doc))
    with pytest.raises(DataError, match="version"):
        GORelocMap.load(tmp_path / "m")
    with pytest.raises(DataError, match="not found"):
        GORelocMap.load(tmp_path / "missing")


def test_an_empty_map_round_trips(world_map, tmp_path):
    empty = GORelocMap(
        ids=np.zeros(0, np.int64),
        centres=np.zeros((0, 3)),
        rotations=np.zeros((0, 3, 3)),
        axes=np.zeros((0, 3)),
        label_counts=np.zeros((0, 80), np.int64),
        edges=np.zeros((0, 2), np.int64),
        instance_labels={},
        K=world_map.K,
        width=320,
        height=240,
        encoder=None,
        categories=[],
        config={},
        stats={},
    )
    empty.save(tmp_path / "m")
    back = GORelocMap.load(tmp_path / "m")
    assert len(back.ids) == 0 and back.adjacency().shape == (0, 0) and len(back.labels) == 0


def test_map_draws_each_ellipsoid_as_points_on_its_surface(world_map):
    mp = world_map.drawn(per_object=50)
    assert len(mp.points) == 50 * len(world_map.ids) and sorted(mp.labels) == sorted(world_map.ids.tolist())
    for k, i in enumerate(world_map.ids):
        local = (mp.points[mp.group == i] - world_map.centres[k]) @ world_map.rotations[k]
        assert np.allclose(((local / world_map.axes[k]) ** 2).sum(1), 1.0)
    assert mp.labels[int(world_map.ids[0])].startswith(f"object {world_map.ids[0]}: ")
