"""The ``mrfswarm`` command: one module per subcommand, errors turned into one line.

Every module of this package that defines ``add_parser(subparsers)`` (which sets
``func``) is a subcommand; they are found, not listed. Every error the toolkit raises on purpose
(:class:`~mrfswarm.errors.MrfswarmError` of the domain, and the numerical layer's, under their common root
:class:`~solvers.errors.SolversError`: bad config, bad input, missing backend) becomes one line on stderr and
exit code 2; no traceback. A config key under an old name
(:class:`~mrfswarm.errors.DeprecatedKeyWarning`), a setting the run does not use
(:class:`~mrfswarm.errors.UnusedSettingWarning`) or what a finished plan warns of
(:class:`~mrfswarm.errors.PlanWarning`, where a command plans through ``plan`` and does not print them itself, as
``mrfswarm run`` does) is one line on stderr too, and the command goes on.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import pkgutil
import signal
import sys
import threading
import warnings
from typing import Any, NoReturn

from mrfswarm.errors import DeprecatedKeyWarning, OutputExistsError, PlanWarning, SolversError, UnusedSettingWarning


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # argparse's default prints usage; one line is enough
        self.exit(2, f"mrfswarm: error: {message}\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="mrfswarm", description="Swarm trajectory planning with MRF optimization.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress to stderr")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    for info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{__name__}.{info.name}")
        if hasattr(mod, "add_parser"):
            mod.add_parser(sub)
    return parser


class Terminated(BaseException):
    """SIGTERM, raised where the command is, so that it stops as on Ctrl-C: its worker processes stopped, no
    output folder half-written (killed outright, the pool's workers outlived the command, holding its pipes)."""


def _terminate(signum: int, frame: Any) -> NoReturn:
    raise Terminated


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    handler = logging.StreamHandler()
    handler.setFormatter(_Formatter())
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, handlers=[handler])
    main_thread = threading.current_thread() is threading.main_thread()
    before = signal.signal(signal.SIGTERM, _terminate) if main_thread else None
    try:
        with warnings.catch_warnings():  # restores showwarning on the way out
            warnings.showwarning = _one_line(warnings.showwarning)
            rc = args.func(args)
    except SolversError as e:  # MrfswarmError and the solvers layer's errors
        # an error whose message also speaks to Python callers has the command's own words (OutputExistsError)
        text = e.command_line if isinstance(e, OutputExistsError) else str(e)
        msg = text.splitlines()[0] if text else type(e).__name__
        print(f"mrfswarm: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("mrfswarm: interrupted", file=sys.stderr)
        if argv is None and main_thread:
            # the command's own process ends here: a second Ctrl-C (or the SIGINT `timeout -s INT` sends the
            # command and then its process group) during the interpreter's exit, where the worker pool joins its
            # threads, printed concurrent.futures' traceback after the line above (6 of 12 runs of swarm100)
            signal.signal(signal.SIGINT, signal.SIG_IGN)
        return 130
    except Terminated:
        print("mrfswarm: terminated", file=sys.stderr)
        return 128 + signal.SIGTERM
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, signal.SIG_DFL if before is None else before)
    return int(rc or 0)


class _Formatter(logging.Formatter):
    """A warning or error as the command's own lines are, ``mrfswarm: warning: ...`` (a deprecated key's, the
    witness windows'); progress (``--verbose``) with the module that logs it."""

    def format(self, record: logging.LogRecord) -> str:
        if record.levelno >= logging.WARNING:
            return f"mrfswarm: {record.levelname.lower()}: {record.getMessage()}"
        return f"{record.levelname} {record.name}: {record.getMessage()}"


def _one_line(show: Any) -> Any:
    """``warnings.showwarning`` that writes a :class:`DeprecatedKeyWarning`, :class:`UnusedSettingWarning` or
    :class:`PlanWarning` as one line, others as ``show`` does."""

    def showwarning(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                    file: Any = None, line: str | None = None) -> None:
        if issubclass(category, (DeprecatedKeyWarning, UnusedSettingWarning, PlanWarning)):
            print(f"mrfswarm: warning: {message}", file=sys.stderr)
        else:
            show(message, category, filename, lineno, file, line)

    return showwarning


if __name__ == "__main__":
    sys.exit(main())
