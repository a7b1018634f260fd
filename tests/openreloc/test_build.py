"""build_object_map end to end on the analytic box room, the saved map and `show-map`."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from openreloc_bench.cli import main
from openreloc_bench.errors import ConfigError
from openreloc_bench.openreloc.build import MappingConfig, build_object_map
from openreloc_bench.openreloc.map import ObjectMap
from openreloc_bench.reconstruction.fusion import FusionConfig
from openreloc_bench.reconstruction.instances import GroupedInstanceConfig
from tests.openreloc.boxworld import MeanColorEncoder, NoisyMaskSegmenter, boxworld_sequence

CFG = MappingConfig(fusion=FusionConfig(voxel_size=0.05))


@pytest.fixture(scope="module")
def seq(tmp_path_factory: pytest.TempPathFactory):
    return boxworld_sequence(tmp_path_factory.mktemp("room"), n_frames=16, hw=(96, 128))


def test_oracle_map(seq, tmp_path: Path) -> None:
    m = build_object_map(seq, CFG, MeanColorEncoder(), progress=False)
    assert {1, 2, 3, 4, 5, 11, 12, 14} <= set(m.landmarks)
    assert m.landmarks[12].category == "sofa"
    assert not m.landmarks[1].valid  # the floor is in every reference frame
    assert all(m.landmarks[i].valid for i in (11, 12, 14))
    assert 0 < m.stats["reference_frames"] < len(seq)
    q = m.stats["instance_quality"]
    assert q["reference"] == "object boxes" and q["recall"] >= 0.85 and q["precision"] >= 0.85, q
    assert set(m.stats["timings_s"]) >= {"fusion", "instances", "reference_frames", "descriptors", "graph"}
    for lm in m.landmarks.values():
        assert np.all(lm.points >= lm.box_min - 1e-5) and np.all(lm.points <= lm.box_max + 1e-5)
        assert np.linalg.norm(lm.descriptor) == pytest.approx(1.0, abs=1e-5)
        assert lm.n_views >= 1
    for rf in m.reference_frames:
        for b in rf.boxes.values():
            assert 0 <= b[0] < b[2] <= seq.width and 0 <= b[1] < b[3] <= seq.height
    # red sofa: its descriptor is nearest to its own mean-colour signature, not the blue cabinet's
    d = m.descriptor_matrix([11, 12])
    assert d[1] @ m.landmarks[12].descriptor > d[0] @ m.landmarks[12].descriptor
    m.save(tmp_path / "map")
    r = ObjectMap.load(tmp_path / "map")
    assert r.valid_ids() == m.valid_ids() and r.graph.number_of_edges() == m.graph.number_of_edges()
    assert main(["show-map", str(tmp_path / "map"), "--out", str(tmp_path / "map.png")]) == 0
    assert (tmp_path / "map.png").stat().st_size > 10_000


def test_segmenter_map_by_clustering_and_fill(seq) -> None:
    instances = GroupedInstanceConfig(grouping="clustering")
    instances.repair.fill = True
    cfg = MappingConfig(fusion=CFG.fusion, instances=instances)
    m = build_object_map(seq, cfg, MeanColorEncoder(), NoisyMaskSegmenter(split_prob=0.0), progress=False)
    assert m.stats["instances_from"] == "segmenter"
    assert m.stats["instance_quality"]["recall"] >= 0.85


def test_no_masks_and_no_segmenter(seq) -> None:
    seq2 = seq.subset(range(len(seq)))
    seq2.records = [type(r)(r.frame_id, r.color_path, r.T_wc, r.depth_path, None) for r in seq2.records]
    with pytest.raises(ConfigError, match="no instance masks and no segmenter"):
        build_object_map(seq2, CFG, MeanColorEncoder(), progress=False)


def test_segmenter_map_by_affinity_grouping(seq) -> None:
    instances = GroupedInstanceConfig(grouping="affinity")
    instances.affinity.min_region_area = 0.05  # 20 points of the 5 cm grid
    cfg = MappingConfig(fusion=CFG.fusion, instances=instances)
    m = build_object_map(seq, cfg, MeanColorEncoder(), NoisyMaskSegmenter(split_prob=0.0), progress=False)
    assert m.config["instances"]["grouping"] == "affinity"
    # 16 views leave floor parts no view sees side by side (test_affinity_grouping: 32 views reach 1.0)
    assert m.stats["instance_quality"]["recall"] >= 0.6
