"""Plugins by module name or file path: found from the working folder, one-line errors, the workers' form."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from openreloc_bench import methods
from openreloc_bench.errors import ConfigError
from openreloc_bench.plugins import is_path, load_plugin, load_plugins
from tests.conftest import FREE_PLUGIN


@pytest.mark.parametrize(
    ("spec", "path"),
    [("hist_nn", False), ("my_pkg.methods", False), ("hist_nn.py", True), ("./hist_nn.py", True), ("p/x", True)],
)
def test_a_plugin_is_a_path_when_it_ends_in_py_or_names_a_folder(spec: str, path: bool) -> None:
    assert is_path(spec) is path


@pytest.mark.parametrize("spec", ["free_plugin", "free_plugin.py", "./free_plugin.py", "sub/../free_plugin.py"])
def test_a_module_or_file_of_the_working_folder_registers_and_resolves_to_its_path(
    plugin_sandbox: Path, monkeypatch: pytest.MonkeyPatch, spec: str
) -> None:
    (plugin_sandbox / "sub").mkdir()
    (plugin_sandbox / "free_plugin.py").write_text(FREE_PLUGIN)
    monkeypatch.chdir(plugin_sandbox)
    assert "free-plugin" not in methods.available_methods()
    resolved = load_plugin(spec)
    assert "free-plugin" in methods.available_methods()
    assert resolved == str((plugin_sandbox / "free_plugin.py").resolve())  # a worker finds it from any folder
    assert load_plugins([spec, resolved, spec]) == [resolved]  # imported once


def test_a_plugin_file_imports_the_modules_beside_it(plugin_sandbox: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (plugin_sandbox / "plugins").mkdir()
    (plugin_sandbox / "plugins" / "helper_of_plugin.py").write_text(FREE_PLUGIN)
    (plugin_sandbox / "plugins" / "main_plugin.py").write_text("import helper_of_plugin  # noqa: F401\n")
    monkeypatch.chdir(plugin_sandbox)
    load_plugin("plugins/main_plugin.py")
    assert "free-plugin" in methods.available_methods()


def test_an_installed_module_stays_a_module_name(plugin_sandbox: Path) -> None:
    """Not a file of the working folder: workers import it by name, as this process did."""
    (plugin_sandbox / "pkg_of_plugin").mkdir()
    (plugin_sandbox / "pkg_of_plugin" / "__init__.py").write_text("")
    (plugin_sandbox / "pkg_of_plugin" / "methods.py").write_text(FREE_PLUGIN)
    sys.path.append(str(plugin_sandbox))
    assert load_plugin("pkg_of_plugin.methods") == "pkg_of_plugin.methods"


@pytest.mark.parametrize(
    ("files", "spec", "message"),
    [
        ({}, "./missing.py", r"^plugin \./missing\.py: no such file \(paths are relative to the working folder, "),
        ({"folder/x.txt": ""}, "./folder", r"^plugin \./folder: is a folder, not a \.py file"),
        ({}, "missing_mod", r"^plugin missing_mod: no module of that name in the working folder .*\./missing_mod\.py"),
        (
            {"raises.py": "x = 1\nraise RuntimeError('no licence\\nserver')\n"},
            "./raises.py",
            r"^plugin \./raises\.py: raises\.py line 2: RuntimeError: no licence server$",
        ),
        (
            {"needs.py": "import numpy\nimport no_such_dependency_xyz\n"},
            "needs",
            r"^plugin needs: needs\.py line 2: ModuleNotFoundError: No module named 'no_such_dependency_xyz'$",
        ),
        ({"broken.py": "def f(:\n"}, "broken.py", r"^plugin broken\.py: broken\.py line 1: SyntaxError: "),
        ({"quits.py": "raise SystemExit(3)\n"}, "quits.py", r"^plugin quits\.py: quits\.py line 1: SystemExit: 3$"),
        (
            {"nothing.py": "x = 1\n"},
            "./nothing.py",
            r"^plugin \./nothing\.py: registers no method \(call openreloc_bench\.methods\.register",
        ),
        ({"json.py": FREE_PLUGIN}, "json.py", r"^plugin json\.py: a module named 'json' is loaded already"),
        ({}, " ", r"^--plugin names nothing"),
        (
            {
                "clash.py": "from baselines.nearest_frame import NearestFrame\nfrom openreloc_bench.methods import register\nregister('nearest-frame', NearestFrame)\n"
            },
            "clash.py",
            r"^plugin clash\.py: clash\.py line 3: ConfigError: method name 'nearest-frame' is taken by baselines\.nearest_frame",
        ),
    ],
)
def test_a_bad_plugin_is_one_line_naming_it_and_the_cause(
    plugin_sandbox: Path, monkeypatch: pytest.MonkeyPatch, files: dict[str, str], spec: str, message: str
) -> None:
    for name, text in files.items():
        (plugin_sandbox / name).parent.mkdir(exist_ok=True)
        (plugin_sandbox / name).write_text(text)
    monkeypatch.chdir(plugin_sandbox)
    with pytest.raises(ConfigError, match=message) as e:
        load_plugin(spec)
    assert "\n" not in str(e.value)
    assert "raises" not in sys.modules  # a failed import leaves no half-run module
