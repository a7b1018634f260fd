"""Where an environment's scene, map and goal embeddings come from: a scene directory, or a suite's
scene generated on first use into a per-user cache, and everything derived from it cached beside it.

Cache layout (``cache_dir``: the env option, else ``$OPENRELOC_BENCH_CACHE``, else
``$XDG_CACHE_HOME/openreloc-bench`` or ``~/.cache/openreloc-bench``)::

    scenes/<suite>/<scene>/                        generated scenes (the generator's layout)
    maps/<method>/<map key>/<scene>-<spec hash>/   relocalizer maps (harness/cache.py's record)
    goals/<scene>-<spec hash>/<encoder hash>.npz   text embeddings of the scene's object descriptions
    renders/<scene>-<spec hash>-<W>x<H>.mjb        the compiled MuJoCo scene (its textures drawn)
    describer/                                     the describers' phrase tables and answers
    locks/                                         one lock file per thing being built

Several processes (the workers of a vector environment) may ask for the same scene or map at once:
each build runs under an exclusive ``fcntl`` lock and is checked again once the lock is held, so it
happens once and the others wait for it. Generation runs in a child process, so the caller never
holds an OpenGL context (contexts and ``fork`` hang; see :mod:`generators.render`).
"""

from __future__ import annotations

import fcntl
import logging
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from openreloc_bench.data.paths import cache_root
from openreloc_bench.data.scene import Scene
from openreloc_bench.errors import ConfigError, DataError
from openreloc_bench.harness.suites import scene_state, suite_file

log = logging.getLogger(__name__)


@contextmanager
def locked(root: Path, name: str) -> Iterator[None]:
    """Hold the exclusive lock ``root/locks/<name>.lock`` (released when the block ends or the process dies)."""
    path = root / "locks" / f"{name}.lock"
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "a") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def resolve_scene(scene: str | None, suite: str, cache_dir: str | Path | None = None) -> Path:
    """The directory of the scene an environment runs in.

    ``scene`` is a generated scene directory (it has a ``scene.json``), or the name of a scene of
    ``suite`` (None: its first scene). ``suite`` is a suite YAML or the name of a bundled suite; its
    scene is generated into the cache unless a complete copy is there (an unfinished one is resumed,
    one of another spec, e.g. from an older generator, replaced: the cache is ours).
    """
    if scene is not None and (Path(scene).expanduser() / "scene.json").is_file():
        return Path(scene).expanduser()
    if scene is not None and (os.sep in scene or Path(scene).expanduser().is_dir()):
        raise ConfigError(f"scene '{scene}': not a generated scene directory (no scene.json)")
    from generators.spec import load_suite, spec_hash

    suite_path = suite_file(suite)
    suite_spec = load_suite(suite_path)
    specs = suite_spec.scene_specs()
    if scene is None:
        spec = specs[0]
    else:
        by_name = {s.name: s for s in specs}
        if scene not in by_name:
            raise ConfigError(
                f"unknown scene '{scene}': neither a scene directory nor a scene of suite "
                f"'{suite_spec.name}' ({', '.join(by_name)})"
            )
        spec = by_name[scene]
    root = cache_root(cache_dir)
    out = root / "scenes" / suite_spec.name
    expected = spec_hash(spec)
    if scene_state(out / spec.name, expected) != "complete":
        with locked(root, f"scene-{suite_spec.name}-{spec.name}"):
            state = scene_state(out / spec.name, expected)
            if state != "complete":
                _generate(suite_path, spec.name, out, state)
    return out / spec.name


def _generate(suite_path: Path, name: str, out: Path, state: str) -> None:
    """Generate one scene of a suite with ``openreloc-bench generate`` in a child process.

    A child started by ``subprocess``, not ``multiprocessing``: spawn and forkserver children run the
    caller's unguarded top-level code again (a script that makes an environment at top level would
    wait for its own lock forever), and the child's OpenGL context dies with it.
    """
    if state == "other spec":  # our cache holds an older generator's copy: replace it
        shutil.rmtree(out / name)
    log.info("generating scene %s of %s into %s (once)", name, suite_path, out)
    cmd = [sys.executable, "-m", "openreloc_bench.cli", "generate", str(suite_path), "--out", str(out)]
    cmd += ["--scenes", name] + (["--resume"] if state == "partial" else [])
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        lines = (res.stderr or res.stdout).strip().splitlines() or [f"exit code {res.returncode}"]
        raise ConfigError(f"generating scene '{name}' of {suite_path} failed: {lines[-1]}")


def scene_key(scene: Scene) -> str:
    """``<scene>-<spec hash>``: cache entries of two scenes of the same name never collide."""
    if not scene.spec_hash:
        raise DataError(scene.root / "scene.json", "no spec_hash: the environments need a generated scene")
    return f"{scene.name}-{scene.spec_hash}"
