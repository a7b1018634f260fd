"""``openreloc-bench leaderboard``: markdown, CSV, sortable HTML and plots from eval and score results."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pandas as pd
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "harness"))
from harness_test_methods import make_scene, perturb  # noqa: E402

from openreloc_bench import methods  # noqa: E402
from openreloc_bench.cli import main  # noqa: E402
from openreloc_bench.data.results import write_results  # noqa: E402
from openreloc_bench.data.scene import Scene  # noqa: E402
from tests.conftest import FREE_PLUGIN  # noqa: E402


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("lb")
    data = root / "data"
    for i, name in enumerate(["s1", "s2"]):
        make_scene(data, name, n_query=5, seed=20 + i)
    assert (
        main(
            [
                "eval",
                "--scenes",
                "s1,s2",
                "--data",
                str(data),
                "--out",
                str(root / "res"),
                "--timeout",
                "0",
                "--methods",
                "test-oracle,nearest-frame",
                "--plugin",
                "harness_test_methods",
                "--track",
                "oracle-mask",
            ]
        )
        == 0
    )
    seq = Scene(data / "s1").sequence("query")
    write_results(root / "sub" / "s1.txt", {n: perturb(T, n, 0.4, 8.0) for n, T in zip(seq.names, seq.poses)})
    assert (
        main(["score", str(root / "sub"), "--data", str(data), "--method", "outside", "--out", str(root / "scores")])
        == 0
    )
    return root, data


def test_leaderboard_merges_eval_and_score_results(results: tuple[Path, Path], capsys) -> None:
    root, _ = results
    out = root / "board"
    assert main(["leaderboard", str(root / "res"), str(root / "scores"), "--out", str(out)]) == 0
    assert "| test-oracle |" in capsys.readouterr().out
    board = pd.read_csv(out / "leaderboard.csv")
    assert set(board["method"]) == {"test-oracle", "nearest-frame", "outside"}
    md = (out / "leaderboard.md").read_text()
    oracle = md.split("## Oracle-mask track")[1].split("## Per scene")[0]
    lines = [ln for ln in oracle.splitlines() if ln.startswith(("| test-oracle |", "| nearest-frame |"))]
    assert lines[0].startswith("| test-oracle")  # sorted by Recall@25cm within (track, split)
    assert md.index("| outside | predicted |") < md.index("| test-oracle | oracle-mask |")  # score's default track
    assert "## Per scene: query" in md and "| outside | 100 / 0 |" in md
    sizes = md.split("## Map size per scene [MB]")[1].split("\n## ")[
        0
    ]  # the maps the eval built; a submission has none
    assert "| test-oracle | oracle-mask |" in sizes and "| nearest-frame | mask-free |" in sizes
    assert "outside" not in sizes and "| s1 | s2 |" in sizes
    page = (out / "index.html").read_text()
    assert '<table class="sortable">' in page and "addEventListener('click'" in page
    assert page.count("<tr>") == len(board) + 1 + 2  # nearest-frame reads no masks: in both tables; a header each
    for name in ("cumulative_translation", "cumulative_rotation", "recall_per_scene", "topdown_s1", "topdown_s2"):
        png = out / "plots" / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f"plots/{name}.png" in page


def test_leaderboard_pools_the_seeds_of_a_variant(results: tuple[Path, Path], tmp_path: Path) -> None:
    root, data = results
    assert (
        main(
            [
                "eval",
                "--scenes",
                "s1,s2",
                "--data",
                str(data),
                "--out",
                str(tmp_path / "res"),
                "--timeout",
                "0",
                "--methods",
                "test-oracle",
                "--seeds",
                "0,3",
                "--plugin",
                "harness_test_methods",
            ]
        )
        == 0
    )
    assert main(["leaderboard", str(tmp_path / "res"), "--out", str(tmp_path / "board")]) == 0
    board = pd.read_csv(tmp_path / "board" / "leaderboard.csv")
    row = board.set_index("method").loc["test-oracle"]  # noise 5 cm and 35 cm: every query within 50, half within 25
    assert (row.n_seeds, row.n_queries, row.recall_50cm, row.recall_25cm) == (2, 20, 100.0, 50.0)
    assert len(board) == 1 and "| Seeds |" in (tmp_path / "board" / "leaderboard.md").read_text()


def test_the_default_board_folder_is_beside_the_results(results: tuple[Path, Path], monkeypatch, capsys) -> None:
    """Without --out the board goes next to the first results folder, not into the working directory's
    (or the repository's) ``leaderboard/``."""
    root, _ = results
    monkeypatch.chdir(root)
    assert main(["leaderboard", "res"]) == 0
    assert (root / "res-board" / "leaderboard.md").is_file() and not (root / "leaderboard").exists()
    assert f"to {root / 'res-board'}" in capsys.readouterr().out


def test_leaderboard_of_an_empty_directory_is_a_clear_error(tmp_path: Path, capsys) -> None:
    assert main(["leaderboard", str(tmp_path), "--out", str(tmp_path / "b")]) == 2
    assert "no tables/queries.csv" in capsys.readouterr().err


def test_leaderboard_heads_with_the_predicted_track(results: tuple[Path, Path], tmp_path: Path) -> None:
    root, data = results
    pred = tmp_path / "pred"
    args = ["eval", "--scenes", "s1", "--data", str(data), "--out", str(pred), "--timeout", "0"]
    assert main([*args, "--methods", "nearest-frame", "--track", "predicted"]) == 0
    out = tmp_path / "board"
    assert main(["leaderboard", str(root / "res"), str(root / "scores"), str(pred), "--out", str(out)]) == 0
    md = (out / "leaderboard.md").read_text()
    verdict = md.splitlines()[2]  # under the title, made from the rows: nearest-frame stands in both tracks
    assert verdict.startswith("**Verdict (query split, recall [%]):** Predicted track: ")
    assert (
        "outside not recorded" in verdict
        and ". Oracle-mask track: test-oracle leads at 50 cm (100.0 vs nearest-frame 20.0, +80.0 [" in verdict
        and "on the same queries" in verdict  # weighed on the queries both answered
    )
    head, oracle = md.index("## Predicted track (headline)"), md.index("## Oracle-mask track (upper bound)")
    assert head < md.index("| outside | predicted |") < oracle < md.index("| test-oracle | oracle-mask |")
    # nearest-frame reads no masks: one row per split, standing in both tables (the last run of it)
    free = [i for i, ln in enumerate(md.splitlines()) if ln.startswith("| nearest-frame | mask-free | query |")]
    assert len(free) == 2 and "| nearest-frame | predicted |" not in md and "| nearest-frame | oracle-mask |" not in md
    assert md.index("## Per scene: query (predicted track)") < md.index("## Per scene: query (oracle-mask track)")
    page = (out / "index.html").read_text()
    assert page.count('<table class="sortable">') == 2 and page.index("Predicted track") < page.index("Oracle-mask")


def _free_plugin_run(data: Path, folder: Path) -> Path:
    """Results of ``free-plugin`` (a plugin file declaring it reads no masks) on the oracle-mask track; the
    plugin is then forgotten, as by a leaderboard rendered in another process."""
    (folder / "free_plugin.py").write_text(FREE_PLUGIN)
    args = ["eval", "--scenes", "s1", "--data", str(data), "--out", str(folder / "res"), "--timeout", "0"]
    assert (
        main([*args, "--methods", "free-plugin", "--track", "oracle-mask", "--plugin", str(folder / "free_plugin.py")])
        == 0
    )
    del sys.modules["free_plugin"]
    del methods._REGISTRY["free-plugin"]  # the sandbox's copy of the registry
    assert "free-plugin" not in methods.available_methods()
    return folder / "res"


def test_a_plugin_reading_no_masks_is_drawn_mask_free_from_its_recorded_track(
    results: tuple[Path, Path], plugin_sandbox: Path
) -> None:
    res = _free_plugin_run(results[1], plugin_sandbox)
    assert main(["leaderboard", str(res), "--out", str(plugin_sandbox / "board")]) == 0
    md = (plugin_sandbox / "board" / "leaderboard.md").read_text()
    assert "| free-plugin | mask-free | query |" in md and "| free-plugin | oracle-mask |" not in md


@pytest.mark.parametrize(("plugin", "track"), [(False, "oracle-mask"), (True, "mask-free")])
def test_tables_from_before_recorded_tracks_are_read_by_the_registered_declaration(
    results: tuple[Path, Path], plugin_sandbox: Path, plugin: bool, track: str
) -> None:
    """Without ``uses_masks`` in the table: a method registered as reading no masks is mask-free (the
    plugin's only with --plugin), any other keeps the track it was run on."""
    root, data = results
    res = _free_plugin_run(data, plugin_sandbox)
    old = shutil.copytree(root / "res", plugin_sandbox / "old")
    for r in (res, old):
        table = r / "tables" / "queries.csv"
        q = pd.read_csv(table).drop(columns="uses_masks")
        q["track"] = q["track"].replace("mask-free", "oracle-mask")  # as an older eval wrote it
        q.to_csv(table, index=False)
    extra = ["--plugin", str(plugin_sandbox / "free_plugin.py")] if plugin else []
    board = plugin_sandbox / "board"
    assert main(["leaderboard", str(res), str(old), "--out", str(board), *extra]) == 0
    md = (board / "leaderboard.md").read_text()
    assert f"| free-plugin | {track} | query |" in md
    assert "| nearest-frame | mask-free | query |" in md and "| test-oracle | oracle-mask | query |" in md
