from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from openreloc_bench import geometry
from openreloc_bench.data.results import (
    hloc_name,
    read_results,
    read_submission,
    read_tum_trajectory,
    write_results,
    write_tum,
)
from openreloc_bench.errors import DataError


@pytest.fixture
def poses() -> dict[str, np.ndarray]:
    rng = np.random.default_rng(3)
    R = Rotation.random(5, random_state=3).as_matrix()
    return {f"query/{i:06d}": geometry.make_pose(R[i], rng.normal(size=3)) for i in range(5)}


def test_round_trip_and_convention(tmp_path: Path, poses):
    path = tmp_path / "poses.txt"
    write_results(path, poses)
    lines = path.read_text().splitlines()
    assert lines[0].startswith("#") and "T_cw" in lines[0]
    # the stored (q, t) is world-to-camera: t = -R^T c
    name, *vals = lines[1].split()
    T_cw = geometry.qt_to_pose(np.array(vals[:4], float), np.array(vals[4:], float))
    np.testing.assert_allclose(T_cw, geometry.invert(poses[name]), atol=1e-8)
    back = read_results(path)
    assert back.keys() == poses.keys()
    for k in poses:
        np.testing.assert_allclose(back[k], poses[k], atol=1e-8)


def test_tum_export_round_trip(tmp_path: Path, poses):
    stamps_in = {n: float(i) for i, n in enumerate(sorted(poses))}
    write_tum(tmp_path / "t.txt", poses, stamps_in)
    stamps, T = read_tum_trajectory(tmp_path / "t.txt")
    assert stamps.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    np.testing.assert_allclose(T, np.stack([poses[k] for k in sorted(poses)]), atol=1e-8)


def test_tum_export_keeps_each_query_stamp_when_others_are_missing(tmp_path: Path, poses):
    """Stamps are the query's own (its index in the split), never its rank among the estimates."""
    names = sorted(poses)
    stamps_in = {n: float(i) for i, n in enumerate(names)}
    write_tum(tmp_path / "t.txt", {n: poses[n] for n in names[2:]}, stamps_in)
    stamps, T = read_tum_trajectory(tmp_path / "t.txt")
    assert stamps.tolist() == [2.0, 3.0, 4.0]
    np.testing.assert_allclose(T[0], poses[names[2]], atol=1e-8)
    with pytest.raises(ValueError, match="no timestamp"):
        write_tum(tmp_path / "u.txt", poses, {})


@pytest.mark.parametrize(
    "line, message",
    [
        ("query/1 1 0 0 0 0 0", "expected 'name qw qx qy qz tx ty tz'"),
        ("query/1 1 0 0 0 0 0 nan", "NaN or inf"),
        ("query/1 2 0 0 0 0 0 0", "not unit"),
        ("query/1 1 0 0 0 0 0 abc", "non-numeric"),
    ],
)
def test_malformed_lines(tmp_path: Path, line, message):
    p = tmp_path / "bad.txt"
    p.write_text(f"# header\n{line}\n")
    with pytest.raises(DataError, match=message):
        read_results(p)


def test_duplicate_names_rejected(tmp_path: Path):
    p = tmp_path / "dup.txt"
    p.write_text("q/1 1 0 0 0 0 0 0\nq/1 1 0 0 0 1 0 0\n")
    with pytest.raises(DataError, match="duplicate query name 'q/1'"):
        read_results(p)


def test_read_submission_takes_confidence_and_hloc_names(tmp_path: Path):
    p = tmp_path / "sub.txt"
    p.write_text("query/color/000012.png 1 0 0 0 1 2 3 0.75\nquery/color/7.jpg 1 0 0 0 0 0 0 2\n")
    poses, confidence = read_submission(p, names="hloc")
    assert confidence == {"query/000012": 0.75, "query/7": 2.0}
    np.testing.assert_allclose(poses["query/000012"][:3, 3], [-1, -2, -3])  # T_cw's inverse
    assert hloc_name("query_light1/color/000003.png") == "query_light1/000003"
    assert hloc_name("query/000003") is None and hloc_name("query/depth/000003.png") is None
    with pytest.raises(DataError, match="expected 'name qw qx qy qz tx ty tz', got 9 fields"):
        read_results(p)  # the benchmark's own files have no confidence column
