"""`openreloc-bench view`: one offline HTML file holding the 3D figure; one-line errors for bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from openreloc_bench.cli import main
from openreloc_bench.data import io, mapfile
from openreloc_bench.data.results import write_results
from openreloc_bench.data.scene import Scene
from openreloc_bench.methods import create_method
from tests.conftest import write_tiny_scene
from tests.openreloc.test_map import make_map


def figure_traces(html: str) -> list[dict]:
    """The traces of the plotly figure a ``view`` page draws (the data argument of ``Plotly.newPlot``)."""
    decoder = json.JSONDecoder()
    i = html.index("Plotly.newPlot(") + len("Plotly.newPlot(")
    _, i = decoder.raw_decode(html, html.index('"', i))  # the div's id
    traces, _ = decoder.raw_decode(html, html.index("[", i))
    return traces


@pytest.fixture
def inputs(tmp_path: Path) -> dict[str, Path]:
    """A tiny scene, a map recorded as built from it, and a pose file of its query split: query 0 at its
    true pose, query 1 a metre off, query 2 missing."""
    scene_dir = write_tiny_scene(tmp_path / "tiny")
    scene = Scene(scene_dir)
    make_map().save(tmp_path / "map")
    mapfile.record_source(tmp_path / "map", {"scene": "tiny", "spec_hash": scene.spec_hash, "track": "oracle-mask"})
    seq = scene.sequence("query")
    off = seq.poses[1].copy()
    off[0, 3] += 1.0
    write_results(tmp_path / "poses.txt", {seq.names[0]: seq.poses[0], seq.names[1]: off})
    return {"scene": scene_dir, "map": tmp_path / "map", "poses": tmp_path / "poses.txt", "tmp": tmp_path}


def test_view_writes_one_offline_html_file_with_the_figure(inputs: dict[str, Path], capsys) -> None:
    out = inputs["tmp"] / "views" / "v.html"
    argv = ["view", str(inputs["map"]), "--scene", str(inputs["scene"]), "--results", str(inputs["poses"])]
    assert main([*argv, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "2/3 queries returned a pose, 1 within 50 cm (recall 33%)" in printed and str(out) in printed
    html = out.read_text()
    assert "<script src=" not in html  # plotly.js is inline: the page opens without a network
    traces = figure_traces(html)
    assert {t["type"] for t in traces} == {"scatter3d"}
    legend = [t["name"] for t in traces if t.get("showlegend", True)]
    assert legend == [
        "landmarks (4)",
        "filtered landmarks (walls, floors...) (1)",
        "reference frames (2)",
        "mapping path (6 frames)",
        "true cameras (2 returned a pose)",
        "no pose returned (1, true cameras)",
        "estimated, within 50 cm (1)",
        "estimated, beyond 50 cm (1)",
    ]
    assert any(text.startswith("landmark 2: cat2<br>valid") for t in traces for text in t.get("text") or [])
    assert sorted(p.name for p in inputs["map"].iterdir()) == ["arrays.npz", "manifest.json", "meta.json"]


def test_view_of_a_map_alone_and_of_an_eval_run_folder(inputs: dict[str, Path], capsys) -> None:
    assert main(["view", str(inputs["map"]), "--out", str(inputs["tmp"] / "a.html"), "--max-points", "10"]) == 0
    names = [t["name"] for t in figure_traces((inputs["tmp"] / "a.html").read_text())]
    assert "reference frames (2)" in names and not any("mapping" in n or "estimated" in n for n in names)
    run = inputs["tmp"] / "runs" / "m" / "oracle-mask" / "tiny"
    run.mkdir(parents=True)
    (run / "query.txt").write_text(inputs["poses"].read_text())
    io.write_json(run / "query.done.json", {"scene": "tiny", "spec_hash": Scene(inputs["scene"]).spec_hash})
    argv = ["view", str(inputs["map"]), "--scene", str(inputs["scene"]), "--results", str(run)]
    assert main([*argv, "--out", str(inputs["tmp"] / "b.html")]) == 0
    assert "estimated, beyond 50 cm (1)" in (inputs["tmp"] / "b.html").read_text()


def other_scene(w: dict[str, Path]) -> str:
    return str(write_tiny_scene(w["tmp"] / "other", seed=1))


def pose_text(w: dict[str, Path], text: str) -> str:
    (w["tmp"] / "bad.txt").write_text(text)
    return str(w["tmp"] / "bad.txt")


def run_folder(w: dict[str, Path], spec: str) -> str:
    run = w["tmp"] / "run"
    run.mkdir(exist_ok=True)
    (run / "query.txt").write_text(w["poses"].read_text())
    io.write_json(run / "query.done.json", {"scene": "elsewhere", "spec_hash": spec})
    return str(run)


def empty_folder(w: dict[str, Path]) -> str:
    (w["tmp"] / "empty").mkdir()
    return str(w["tmp"] / "empty")


# (extra arguments, given the inputs; the text of the one-line error)
MISTAKES = {
    "a folder that is not a map": (lambda w: [str(w["scene"]), "--out", "v.html"], "no map manifest here"),
    "a map of another scene": (
        lambda w: [str(w["map"]), "--scene", other_scene(w), "--out", "v.html"],
        "is a map of scene 'tiny'",
    ),
    "a pose file that does not parse": (
        lambda w: [str(w["map"]), "--scene", str(w["scene"]), "--results", pose_text(w, "query/000000 1 0 0\n")],
        "line 1: expected 'name qw qx qy qz tx ty tz [confidence]', got 4 fields",
    ),
    "a pose file naming a frame the scene lacks": (
        lambda w: [
            str(w["map"]),
            "--scene",
            str(w["scene"]),
            "--results",
            pose_text(w, "query/000099 1 0 0 0 0 0 0\n"),
        ],
        "names 'query/000099', which",
    ),
    "a pose file of another split": (
        lambda w: [
            str(w["map"]),
            "--scene",
            str(w["scene"]),
            "--results",
            pose_text(w, "mapping/000000 1 0 0 0 0 0 0\n"),
        ],
        "names no query of split 'query'",
    ),
    "a run folder of another scene": (
        lambda w: [str(w["map"]), "--scene", str(w["scene"]), "--results", run_folder(w, "tiny-9")],
        "is a run on scene 'elsewhere' (spec tiny-9)",
    ),
    "a folder that is no run": (
        lambda w: [str(w["map"]), "--scene", str(w["scene"]), "--results", empty_folder(w)],
        "no query.txt here",
    ),
    "results without a scene": (lambda w: [str(w["map"]), "--results", str(w["poses"])], "--results needs --scene"),
    "--out inside the map": (lambda w: [str(w["map"]), "--out", str(w["map"] / "v.html")], "overlaps the input"),
    "--out inside the scene": (
        lambda w: [str(w["map"]), "--scene", str(w["scene"]), "--out", str(w["scene"] / "v.html")],
        "overlaps the input",
    ),
    "--out not HTML": (lambda w: [str(w["map"]), "--out", "v.png"], "must end in .html"),
    "no points": (lambda w: [str(w["map"]), "--max-points", "0"], "--max-points must be >= 1"),
}


@pytest.mark.parametrize("case", MISTAKES)
def test_bad_inputs_fail_with_one_line(case: str, inputs: dict[str, Path], capsys, monkeypatch) -> None:
    monkeypatch.chdir(inputs["tmp"])
    args, expected = MISTAKES[case]
    argv = ["view", *args(inputs)]
    if "--out" not in argv:
        argv += ["--out", "v.html"]
    before = {p: p.read_bytes() for d in (inputs["map"], inputs["scene"]) for p in d.rglob("*") if p.is_file()}
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("openreloc-bench view: error: ") and expected in err, err
    assert not (inputs["tmp"] / "v.html").exists()
    after = {p: p.read_bytes() for d in (inputs["map"], inputs["scene"]) for p in d.rglob("*") if p.is_file()}
    assert after == before


def test_help(capsys) -> None:
    with pytest.raises(SystemExit) as e:
        main(["view", "--help"])
    assert e.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "usage: openreloc-bench view" in text and "MAPDIR" in text and "--results RUN_OR_POSE_FILE" in text
    assert (
        "self-contained HTML file" in text
        and "--max-points MAX_POINTS map points drawn at most (default: 60000)" in text
    )


def test_view_of_a_map_of_another_method(inputs: dict[str, Path], capsys) -> None:
    """A method without map points (nearest-frame) is drawn with the scene's mapping path; its name
    comes from the map's format and leads the title."""
    scene = Scene(inputs["scene"])
    create_method("nearest-frame").build_map(scene.sequence("mapping"), inputs["tmp"] / "nf")
    out = inputs["tmp"] / "nf.html"
    argv = ["view", str(inputs["tmp"] / "nf"), "--out", str(out)]
    assert main(argv) == 2
    assert "method 'nearest-frame' keeps no 3D points it can draw" in capsys.readouterr().err
    assert main([*argv, "--scene", str(inputs["scene"]), "--results", str(inputs["poses"])]) == 0
    assert capsys.readouterr().out.startswith("nearest-frame: keeps no 3D points; 2/3 queries returned a pose")
    assert "mapping path (6 frames)" in [t["name"] for t in figure_traces(out.read_text())]


def test_view_needs_a_method_for_a_format_no_method_has(inputs: dict[str, Path], capsys) -> None:
    mapfile.write_file_set(inputs["tmp"] / "odd", "odd-map", 1, {"x.bin": b"1"})
    argv = ["view", str(inputs["tmp"] / "odd"), "--out", str(inputs["tmp"] / "v.html")]
    assert main(argv) == 2
    assert "no method is registered for map format 'odd-map': give it with --method" in capsys.readouterr().err
    assert main([*argv, "--method", "nope"]) == 2
    assert "unknown method 'nope'" in capsys.readouterr().err
    assert main([*argv, "--method", "sift-pnp"]) == 2  # the method's own reader refuses the format
    assert "sift-pnp-map" in capsys.readouterr().err
