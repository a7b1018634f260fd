"""Suites on disk: the scenes a suite names, and generating the ones missing or unfinished under DATA.

The generator is imported lazily, so scoring existing scenes works where it is not installed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from openreloc_bench.data import io, paths
from openreloc_bench.data.scene import (
    DATA_VERSION,
    SceneWriter,
    check_scene_info,
    generated_data_version,
    other_version,
)
from openreloc_bench.errors import ConfigError

SUITES_DIR = Path(__file__).resolve().parents[2] / "scenes"
"""The checkout's bundled suite YAMLs (``smoke``, ``demo``, ``validation``, ...)."""


def suite_file(suite: str | Path) -> Path:
    """A suite YAML (a path ending in .yaml / .yml), or the name of a bundled suite; ConfigError naming
    the bundled ones when it is neither."""
    text = str(suite)
    path = Path(text).expanduser() if text.endswith((".yaml", ".yml")) else SUITES_DIR / f"{text}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in SUITES_DIR.glob("*.yaml"))
        raise ConfigError(
            f"suite '{text}' not found (a suite YAML, or one of: {', '.join(known) or 'none in this installation'})"
        )
    return path


def suite_spec(suite_path: Path) -> Any:
    """The suite (``generators.spec.SuiteSpec``: name, purpose, description, scenes), validated."""
    try:
        from generators.spec import load_suite
    except ImportError as e:
        raise ConfigError(f"the scene generator is not available ({e}); use --scenes with existing scenes") from None
    return load_suite(suite_path)


def suite_specs(suite_path: Path) -> list[Any]:
    """The suite's scene specs (``generators.spec.SceneSpec``), validated."""
    return suite_spec(suite_path).scene_specs()


def suite_scene_names(suite_path: Path) -> list[str]:
    """Names of a suite's scenes (no generation)."""
    return [s.name for s in suite_specs(suite_path)]


def ensure_suite_scenes(suite_path: Path, data: Path) -> list[str]:
    """Scene names of a suite, generating the missing ones and resuming the unfinished ones under ``data``.

    A scene of the same name generated from another spec is never replaced: that is the user's data.
    """
    specs = suite_specs(suite_path)
    from generators.spec import spec_hash

    def todo() -> list[tuple[Any, str]]:
        out = []
        for spec in specs:
            paths.check_output(data / spec.name, [suite_path], "scene directory")
            state = scene_state(data / spec.name, spec_hash(spec))
            if state == "other spec":
                version = _data_version(data / spec.name)
                if version not in (None, DATA_VERSION):
                    raise ConfigError(
                        f"{data / spec.name} was {other_version(version)}: generate the suite into another --data "
                        f"(`openreloc-bench generate {suite_path} --out DIR`)"
                    )
                raise ConfigError(
                    f"{data / spec.name} was generated from another spec than {suite_path} asks for; "
                    "move it away or use another --data"
                )
            if state != "complete":
                out.append((spec, state))
        return out

    if todo():
        from generators.generate import generate_scene

        with paths.directory_lock(data, "openreloc-bench generate", in_directory=False):
            for spec, state in todo():  # again under the lock: another process may have generated meanwhile
                print(f"generating scene {spec.name} ({state}) ...", flush=True)
                generate_scene(spec, data, resume=state == "partial")
    return [s.name for s in specs]


def _data_version(root: Path) -> int | None:
    info_path = root / "scene.json"
    return generated_data_version(io.read_json(info_path)) if info_path.is_file() else None


def scene_state(root: Path, expected_hash: str) -> str:
    """'complete', 'partial' (same spec, frames missing or damaged: resume it), 'missing' or 'other spec'."""
    info_path = root / "scene.json"
    if not info_path.is_file():
        return "missing" if not root.exists() or not any(root.iterdir()) else "other spec"
    info = check_scene_info(io.read_json(info_path), info_path)
    if info.get("spec_hash") != expected_hash:
        return "other spec"
    counts = info.get("splits") or {}
    writer = SceneWriter(root)
    done = all(writer.has_frame(s, i) for s, n in counts.items() for i in range(n))
    return "complete" if counts and done else "partial"
