from pathlib import Path

import numpy as np
import pytest

from openreloc_bench import geometry
from openreloc_bench.data import io
from openreloc_bench.data.tum import read_tum
from openreloc_bench.errors import DataError


def write_tum_sequence(root: Path) -> Path:
    """Colour at 30 Hz, depth offset by 5 ms, ground truth at 100 Hz, one colour frame without depth."""
    rgb, dep = [], []
    for i in range(6):
        t = 1305031102.0 + i / 30
        io.write_png(root / "rgb" / f"{t:.6f}.png", np.full((12, 16, 3), i * 20, np.uint8))
        rgb.append(f"{t:.6f} rgb/{t:.6f}.png")
        if i != 3:
            td = t + 0.005
            io.write_png(root / "depth" / f"{td:.6f}.png", np.full((12, 16), 5000 * (i + 1), np.uint16))
            dep.append(f"{td:.6f} depth/{td:.6f}.png")
    (root / "rgb.txt").write_text("# colour images\n" + "\n".join(rgb) + "\n")
    (root / "depth.txt").write_text("# depth maps\n" + "\n".join(dep) + "\n")
    gt = ["# timestamp tx ty tz qx qy qz qw"]
    for k in range(30):
        t = 1305031102.0 + k / 100
        gt.append(f"{t:.4f} {k * 0.01:.4f} 0 1.5 0 0 0 1")
    (root / "groundtruth.txt").write_text("\n".join(gt) + "\n")
    return root


def test_association_depth_factor_and_poses(tmp_path: Path):
    seq = read_tum(write_tum_sequence(tmp_path / "fr1"))
    assert len(seq) == 5 and len(seq.skipped) == 1 and seq.root == tmp_path / "fr1"
    f = seq[1]
    assert np.allclose(f.depth, 2.0)  # 10000 / 5000
    t_rgb = 1 / 30
    assert f.T_wc[0, 3] == pytest.approx(round(t_rgb * 100) / 100, abs=1e-6)
    assert geometry.is_rigid(f.T_wc)


def test_malformed_groundtruth(tmp_path: Path):
    root = write_tum_sequence(tmp_path / "fr1")
    (root / "groundtruth.txt").write_text("1305031102.0 0 0 0 0 0 0\n")
    with pytest.raises(DataError, match="groundtruth.txt: line 1"):
        read_tum(root)


def test_a_timestamp_listed_twice_is_refused(tmp_path: Path):
    root = write_tum_sequence(tmp_path / "fr1")
    lines = (root / "rgb.txt").read_text().splitlines()
    (root / "rgb.txt").write_text("\n".join([*lines[:3], lines[2], *lines[3:]]) + "\n")
    with pytest.raises(DataError, match="rgb.txt: line 4: timestamp .* is listed twice \\(first on line 3\\)"):
        read_tum(root)
