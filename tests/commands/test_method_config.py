"""``openreloc-bench config METHOD``: documented settings that ``--method-config`` reads back."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from openreloc_bench import config
from openreloc_bench.cli import main
from openreloc_bench.commands.eval import method_runs
from openreloc_bench.harness.runner import seeded_runs
from openreloc_bench.methods import available_methods, create_method


@pytest.mark.parametrize("name", sorted(available_methods()))
def test_printed_settings_are_the_defaults_and_read_back(name: str, tmp_path: Path, capsys) -> None:
    assert main(["config", name]) == 0
    text = capsys.readouterr().out
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    (run, method), *_ = seeded_runs(method_runs([name], [f"{name}={path}"], False), [])
    assert method.config == create_method(name).config and run.overrides
    lines = text.splitlines()
    undocumented = [
        b for a, b in zip(lines, lines[1:]) if not (a.lstrip().startswith("#") or b.lstrip().startswith("#"))
    ]
    assert not undocumented  # every setting, and every section, has its documentation above it


def test_settings_are_documented_and_nested(capsys) -> None:
    assert main(["config", "openreloc"]) == 0
    text = capsys.readouterr().out
    cfg = create_method("openreloc").config
    docs = config.field_docs(type(cfg.association))
    assert f"  # {docs['top_k']}" in text and f"\n  top_k: {cfg.association.top_k}\n" in text
    assert f"\nassociation:\n  # {docs['top_k']}" in text
    assert all(f"\n{f.name}:" in text for f in dataclasses.fields(cfg))


def test_changes_are_shown_and_errors_are_one_line(tmp_path: Path, capsys) -> None:
    assert main(["config", "nearest-frame", "--set", "thumb_size=16"]) == 0
    out = capsys.readouterr().out
    assert "with the given changes" in out and "\nthumb_size: 16\n" in out
    assert main(["config", "nearest-frame", "--set", "thumb_size=2"]) == 2
    assert main(["config", "no-such-method"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "thumb_size" in err[0] and "unknown method 'no-such-method'" in err[1]


def test_commented_yaml_quotes_text_that_reads_as_another_type() -> None:
    @dataclasses.dataclass
    class Odd:
        name: str = "true"
        """A name that YAML would read as a boolean."""
        values: tuple[float, ...] = (1e-5, 2.0)

    text = config.commented_yaml(Odd())
    assert "name: 'true'" in text and "# A name that YAML" in text
    assert config.from_dict(Odd, config.parse_yaml(text)) == Odd()
