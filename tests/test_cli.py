import argparse
import subprocess
import sys

from openreloc_bench.cli import build_parser, command_modules, main


def test_every_command_is_documented():
    mods = command_modules()
    assert "methods" in {m.NAME for m in mods}
    help_text = build_parser().format_help()
    for m in mods:
        assert m.NAME in help_text and m.HELP
        assert m.__doc__, f"command {m.NAME} needs a module docstring (its --help description)"


def test_methods_lists_nearest_frame(capsys):
    assert main(["methods"]) == 0
    assert "nearest-frame" in capsys.readouterr().out


def test_console_script_help_and_user_error():
    exe = [sys.executable, "-m", "openreloc_bench.cli"]
    out = subprocess.run(exe + ["--help"], capture_output=True, text=True)
    assert out.returncode == 0 and "methods" in out.stdout
    bad = subprocess.run(exe + ["methods", "--bogus"], capture_output=True, text=True)
    assert bad.returncode == 2 and "unrecognized arguments" in bad.stderr


def _log_lines(verbose: bool) -> str:
    code = (
        "import logging\n"
        "from openreloc_bench.cli import configure_logging\n"
        f"configure_logging({verbose})\n"
        "logging.getLogger('OpenGL.acceleratesupport').info('No OpenGL_accelerate module loaded')\n"
        "logging.getLogger('sentence_transformers').debug('Loading SentenceTransformer model')\n"
        "logging.getLogger('openreloc_bench.harness').info('ours')\n"
        "logging.getLogger('openreloc_bench.harness').debug('our detail')\n"
    )
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stderr


def test_other_libraries_info_lines_show_only_with_verbose():
    quiet, verbose = _log_lines(False), _log_lines(True)
    assert "INFO openreloc_bench.harness: ours" in quiet and "our detail" not in quiet
    assert "OpenGL_accelerate" not in quiet and "SentenceTransformer" not in quiet
    assert "INFO OpenGL.acceleratesupport: No OpenGL_accelerate" in verbose
    assert "SentenceTransformer" in verbose and "our detail" in verbose


def test_a_closed_output_pipe_ends_non_zero_in_one_line() -> None:
    """`openreloc-bench ... | head -1`: the command stops when its reader goes away, and says so."""
    proc = subprocess.Popen(
        [sys.executable, "-c", "from openreloc_bench.cli import main; import sys; sys.exit(main(['methods']))"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    proc.stdout.close()  # the reader is gone before the first line
    err = proc.stderr.read()
    assert proc.wait() == 141 and err == "openreloc-bench methods: stopped: its output was closed (by `| head`?)\n", err


def test_positional_arguments_are_named_in_capitals():
    """Usage lines name what a user types in one case (``generate SUITE``, ``view MAPDIR``), choices aside."""
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for name, parser in sub.choices.items():
        for action in parser._actions:
            if not action.option_strings and action.choices is None:
                assert action.metavar and action.metavar.isupper(), f"{name}: positional '{action.dest}'"
