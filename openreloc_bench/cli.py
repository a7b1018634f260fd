"""``openreloc-bench``: one sub-command per module in :mod:`openreloc_bench.commands` (hloc style).

Each command module defines ``NAME``, ``HELP``, ``add_arguments(parser)`` and ``run(args) -> int``;
``--plugin`` (:func:`~openreloc_bench.commands.options.add_plugin_argument`) is imported before ``run``.
User mistakes (:class:`~openreloc_bench.errors.OpenRelocError`) and file operations the system
refuses (``OSError``: read-only file system, permissions, disk full) are printed as one line with a
non-zero exit (``-v`` keeps the traceback of the latter); anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import os
import pkgutil
import signal
import sys
import traceback
from types import ModuleType

from openreloc_bench import __version__, commands
from openreloc_bench.commands.options import load_plugin_arguments
from openreloc_bench.errors import OpenRelocError, PluginError

log = logging.getLogger("openreloc_bench")


def command_modules() -> list[ModuleType]:
    mods = [importlib.import_module(f"{commands.__name__}.{m.name}") for m in pkgutil.iter_modules(commands.__path__)]
    return sorted((m for m in mods if hasattr(m, "NAME")), key=lambda m: getattr(m, "ORDER", 50))


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the descriptions' line breaks and ends each option's help with its default, ``(default:
    VALUE)``, unless the help gives it already (in the same words) or there is none (None, off, empty)."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        d = action.default
        unset = d is None or d is False or d is argparse.SUPPRESS or (isinstance(d, (str, list)) and not d)
        named = action.option_strings or action.nargs in (argparse.OPTIONAL, argparse.ZERO_OR_MORE)
        if unset or not named or "(default: " in text:
            return action.help
        return f"{text} (default: %(default)s)".lstrip()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="openreloc-bench",
        description="Object-level indoor camera relocalization: scene generator, OpenReLoc, baselines, harness.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"openreloc-bench {__version__}")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="debug logging, with other libraries' INFO and DEBUG lines"
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in command_modules():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=mod.__doc__, formatter_class=HelpFormatter)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


OWN_LOGGERS = ("openreloc_bench", "generators", "baselines")


def configure_logging(verbose: bool) -> None:
    """This project's INFO lines; other libraries' (PyOpenGL's accelerate notice, sentence-transformers,
    numexpr) only from WARNING up, unless ``verbose`` (``-v``), which shows every library's DEBUG."""
    logging.basicConfig(
        level=logging.DEBUG if verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s"
    )
    for name in OWN_LOGGERS:
        logging.getLogger(name).setLevel(logging.DEBUG if verbose else logging.INFO)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    configure_logging(args.verbose)
    if not getattr(args, "_run", None):
        parser.print_help()
        return 2
    try:
        load_plugin_arguments(args)  # before the command: its methods are then registered
        return int(args._run(args) or 0)
    except OpenRelocError as e:
        if args.verbose and isinstance(e, PluginError) and e.__cause__ is not None:
            traceback.print_exception(e.__cause__)  # where in the plugin, in full
        print(f"openreloc-bench {args.command}: error: {e}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (`| head`): the work stopped unfinished, so not 0
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # no second error when Python flushes
        print(f"openreloc-bench {args.command}: stopped: its output was closed (by `| head`?)", file=sys.stderr)
        return 128 + signal.SIGPIPE
    except OSError as e:  # the system refused a file operation: read-only file system, permissions, disk full
        if args.verbose:
            raise
        where = f": {e.filename}" if e.filename else ""
        print(f"openreloc-bench {args.command}: error: {e.strerror or e}{where}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        again = "; rerun with --resume to go on" if hasattr(args, "resume") else ""
        print(f"openreloc-bench {args.command}: interrupted{again}", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
