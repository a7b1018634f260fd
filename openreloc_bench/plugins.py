"""Plugins: a module or a Python file that registers methods with :func:`openreloc_bench.methods.register`.

A plugin is named by a module name (``hist_nn``, ``my_package.methods``: importable from the environment
or from the working folder) or by the path of a ``.py`` file (``./hist_nn.py``, ``plugins/hist_nn.py``:
relative to the working folder). Every process that creates the plugin's methods imports it: the CLI
process, and each worker of an evaluation, given the form :func:`load_plugins` returns (absolute paths)
so that it finds the same file whatever its working folder.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
import traceback
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType

from openreloc_bench import methods
from openreloc_bench.errors import ConfigError, described


def is_path(spec: str) -> bool:
    """Whether ``spec`` names a file (a ``.py`` name or a path with a folder), not a module."""
    return spec.endswith(".py") or "/" in spec or os.sep in spec


def load_plugins(specs: Iterable[str]) -> list[str]:
    """Import each plugin once per process; returns each as worker processes import it (see :func:`load_plugin`)."""
    return list(dict.fromkeys(load_plugin(s) for s in specs))


def load_plugin(spec: str) -> str:
    """Import one plugin unless this process has; returns the form that imports the same code from any
    working folder: a file's absolute path (also for a single-file module found in the working folder),
    else the module name. ConfigError, one line naming the plugin and the cause, when it is not found,
    raises as it runs, or registers no method."""
    if not spec.strip():
        raise ConfigError("--plugin names nothing: give a module name or a .py file")
    before = methods.registered()
    if is_path(spec):
        path = Path(spec).expanduser().resolve()
        module, new = _import_file(spec, path)
        resolved = str(path)
    else:
        module, new = _import_module(spec)
        resolved = _worker_form(spec, module)
    after = methods.registered()
    if new and not any(before.get(name) is not factory for name, factory in after.items()):
        raise ConfigError(
            f"plugin {spec}: registers no method (call openreloc_bench.methods.register('my-method', MyClass) in it)"
        )
    return resolved


def _import_file(spec: str, path: Path) -> tuple[ModuleType, bool]:
    if not path.is_file():
        what = "is a folder, not a .py file" if path.is_dir() else "no such file"
        raise ConfigError(f"plugin {spec}: {what} (paths are relative to the working folder, {Path.cwd()})")
    name = path.stem
    loaded = sys.modules.get(name)
    if loaded is not None:
        if _file_of(loaded) == path:
            return loaded, False
        raise ConfigError(
            f"plugin {spec}: a module named '{name}' is loaded already (from {_file_of(loaded) or 'Python'}); "
            "rename the file"
        )
    module_spec = importlib.util.spec_from_file_location(name, path)
    if module_spec is None or module_spec.loader is None:
        raise ConfigError(f"plugin {spec}: not a Python file Python can import")
    module = importlib.util.module_from_spec(module_spec)
    sys.modules[name] = module  # before running it: dataclasses and pickling look the module up by name
    _append_path(path.parent)  # as for a script: the modules beside it import
    try:
        module_spec.loader.exec_module(module)
    except (Exception, SystemExit) as e:
        del sys.modules[name]
        raise ConfigError(f"plugin {spec}: {_cause(e)}") from None
    return module, True


def _import_module(spec: str) -> tuple[ModuleType, bool]:
    if spec in sys.modules:
        return sys.modules[spec], False
    _append_path(Path.cwd())  # the console script, unlike `python -m`, leaves the working folder off the path
    try:
        return importlib.import_module(spec), True
    except ModuleNotFoundError as e:
        if e.name is not None and (spec == e.name or spec.startswith(f"{e.name}.")):
            raise ConfigError(
                f"plugin {spec}: no module of that name in the working folder ({Path.cwd()}) or the environment "
                f"(a file path such as ./{spec.replace('.', '/')}.py works too)"
            ) from None
        raise ConfigError(f"plugin {spec}: {_cause(e)}") from None
    except (Exception, SystemExit) as e:
        raise ConfigError(f"plugin {spec}: {_cause(e)}") from None


def _worker_form(spec: str, module: ModuleType) -> str:
    """A single-file module of the working folder as its path (a worker's working folder may differ)."""
    file = _file_of(module)
    if "." not in spec and file is not None and file.name == f"{spec}.py" and file.parent == Path.cwd().resolve():
        return str(file)
    return spec


def _file_of(module: ModuleType) -> Path | None:
    file = getattr(module, "__file__", None)
    return Path(file).resolve() if file else None


def _append_path(folder: Path) -> None:
    """At the end of ``sys.path``: installed modules keep their names."""
    if str(folder) not in sys.path:
        sys.path.append(str(folder))


def _cause(e: BaseException) -> str:
    """``<file> line <n>: <Error>: <message>`` on one line, at the plugin's line that raised (the first
    frame past this module and Python's import machinery)."""
    if isinstance(e, SyntaxError) and e.filename:
        return f"{Path(e.filename).name} line {e.lineno}: SyntaxError: {e.msg}"
    frames = [f for f in traceback.extract_tb(e.__traceback__) if not _is_machinery(f.filename)]
    return described(e, frames[0] if frames else None)


def _is_machinery(filename: str) -> bool:
    path = Path(filename).resolve()
    return (
        filename.startswith("<")
        or path == Path(__file__).resolve()
        or path.parent == Path(importlib.__file__).parent.resolve()
    )
