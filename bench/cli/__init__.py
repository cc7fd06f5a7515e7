"""``skidbench`` command line (argparse + rich progress bars).

    skidbench list
    skidbench simulate SCENARIO --seed N [--set key=value ...] -o run.parquet
    skidbench validate-testbed [--json] [--quick]
    skidbench estimate METHOD RUN.parquet [--calibrate RUN ...] -o est.csv
    skidbench reproduce [PAPER ...] [--all] [--quick] [--workers N] [--dask-scheduler ADDR]

Errors in inputs (spec files, logs) are printed as one line naming file, field and value, exit 2.

This module is the entry point (the parser, :data:`COMMANDS`, :func:`main` and its error handling); each command
group registers itself from its own module: :mod:`bench.cli.simulate` (list, simulate, validate-testbed,
estimate), :mod:`bench.cli.reproduce` (reproduce, compare, the extras and their result cache; the real-data extra
in :mod:`bench.cli.real`), :mod:`bench.cli.formats` (import-drive, export-tum, import-csv, import-bag),
:mod:`bench.cli.verify` (verify-runs), :mod:`bench.cli.dashboard`, :mod:`bench.cli.gap`.
"""
from __future__ import annotations

import argparse
import errno
import os
import sys
import warnings
from pathlib import Path
from typing import Any, Callable, Sequence

from bench.run import RunError
from bench.spec import SpecError

COMMANDS: dict[str, tuple[Callable[[argparse.ArgumentParser], None], Callable[[argparse.Namespace], int], str]] = {}


def command(name: str, help_: str):
    def deco(fn_pair):
        COMMANDS[name] = (*fn_pair, help_)
        return fn_pair
    return deco


def _progress():
    from rich.console import Console
    from rich.progress import (BarColumn, Progress, TaskProgressColumn, TextColumn, TimeElapsedColumn,
                               TimeRemainingColumn)

    # on stderr, with the log lines printed through it: stdout keeps only a command's result lines.  Drawn
    # only on a terminal (as tqdm's disable=None): a log file or a pipe gets the log lines, not a bar frozen at
    # whatever it showed when the output was flushed, and an error stays the one line on stderr.
    # TaskProgressColumn: the percentage, blank while a bar has no total (pulsing) instead of "0.0%"
    console = Console(stderr=True, soft_wrap=True)  # a log line is not wrapped at 80 columns off a terminal
    return Progress(TextColumn("{task.description}"), BarColumn(), TaskProgressColumn(), TimeElapsedColumn(),
                    TimeRemainingColumn(), transient=False, console=console, disable=not console.is_terminal)


def parse_sets(items: Sequence[str] | None) -> dict[str, Any]:
    from bench.spec import parse_override

    return dict(parse_override(s) for s in (items or ()))


def build_parser() -> argparse.ArgumentParser:
    _load_optional_commands()
    ap = argparse.ArgumentParser(prog="skidbench", description=__doc__.split("\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    for name, (add_args, _fn, help_) in COMMANDS.items():
        sp = sub.add_parser(name, help=help_)
        add_args(sp)
    return ap


def _load_optional_commands() -> None:
    """Commands defined next to their feature (reproduce, gap, formats, ...) register themselves."""
    import importlib

    for mod in ("bench.cli.simulate", "bench.cli.reproduce", "bench.cli.formats", "bench.cli.verify",
                "bench.cli.dashboard", "bench.cli.gap", "bench.cli.evaluate", "bench.cli.real"):
        try:
            importlib.import_module(mod)
        except ModuleNotFoundError as exc:
            if exc.name != mod:
                raise


def count(minimum: int) -> Callable[[str], int]:
    """An argparse type: an integer >= ``minimum`` (``--workers 0`` or ``--seed -1`` is a usage error, exit 2)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value} must be >= {minimum}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


def unwritable_folder(first: Path) -> Path | None:
    """The nearest existing one of ``first`` and its parents when it is not a folder this user can write into, else
    None: where an output that would be written at or under ``first`` cannot go."""
    folder = next((p for p in [first.absolute(), *first.absolute().parents] if p.exists()), None)
    return folder if folder is not None and not (folder.is_dir() and os.access(folder, os.W_OK | os.X_OK)) else None


def output_files(a: argparse.Namespace, *names: str) -> None:
    """Each output file ``--NAME`` given on the command line is a file name, not a folder, in a folder this user can
    write (the nearest existing one): checked before anything is computed or written, so that one bad name leaves no
    other file behind and a long run does not end on it."""
    for name in names:
        path = getattr(a, name, None)
        if path is None:
            continue
        flag = f"--{name.replace('_', '-')}"
        if Path(path).is_dir():
            raise SpecError("<command line>", flag, str(path), "a file name, not a folder")
        if (folder := unwritable_folder(Path(path).parent)) is not None:
            raise SpecError("<command line>", flag, str(path), f"cannot be written: {folder} is not a writable folder")


def main(argv: Sequence[str] | None = None) -> int:
    """The ``skidbench`` program.  Called as a program (``argv`` None) it first re-executes itself with numpy's
    and OpenBLAS's CPU dispatch pinned (:func:`bench.cpu.reexec_pinned`: the same runs on any x86-64 CPU)."""
    if argv is None:
        from bench.cpu import reexec_pinned

        reexec_pinned()
    ap = build_parser()
    a = ap.parse_args(argv)
    # warnings of this process are held until the command ends: shown after it when it succeeds, fails on a defect or
    # is interrupted, dropped when it stops on bad input, whose report is one line (numpy's "invalid value" on a bad
    # column came before it).  A forked worker inherits the hook but prints its warnings as they come.
    held: list[tuple] = []
    show, pid = warnings.showwarning, os.getpid()

    def hold(*w: Any) -> None:
        if os.getpid() == pid:
            held.append(w)
        else:
            show(*w)

    try:
        with warnings.catch_warnings():
            warnings.showwarning = hold
            code = COMMANDS[a.cmd][1](a)
    except KeyboardInterrupt:
        _replay(held, show)
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        if not _stdout_gone():  # another pipe (a worker's, a child's): a defect, reported as one
            _replay(held, show)
            raise
        # the reader of stdout went away (`skidbench ... | head`): stop quietly, exit 1 (as rich does)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # the interpreter's final flush goes nowhere
        return 1
    except Exception as exc:
        if isinstance(exc, OSError) and exc.errno in MACHINE_ERRNOS:  # the machine's failure, not the input's
            _replay(held, show)
            print(f"error: {_one_line(exc)}", file=sys.stderr)
            return 1
        if _input_error(exc):
            print(f"error: {_one_line(exc)}", file=sys.stderr)
            return 2
        _replay(held, show)
        raise
    except BaseException:  # SystemExit
        _replay(held, show)
        raise
    _replay(held, show)
    return code


def _stdout_gone() -> bool:
    """True when stdout is a pipe whose reader has closed it (poll reports an error on its write end)."""
    try:
        import select

        poll = select.poll()
        poll.register(sys.stdout.fileno(), select.POLLOUT)
        return any(ev & (select.POLLERR | select.POLLHUP) for _, ev in poll.poll(0))
    except (OSError, ValueError, AttributeError):  # no file descriptor (captured), no poll
        return False


def _replay(held: list[tuple], show: Callable[..., None]) -> None:
    for w in held:
        show(*w)


MACHINE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.ENOMEM})  # one line, but exit 1: not bad input


def _one_line(exc: Exception) -> str:
    """The message of an input error on one line: an OSError names its path, a KeyError the missing key."""
    if isinstance(exc, OSError) and exc.filename is not None:
        return f"{exc.filename}: {exc.strerror or exc}"
    if isinstance(exc, KeyError) and exc.args:
        key = exc.args[0]
        return key if isinstance(key, str) and " " in key else f"missing key or column {key!r}"
    return " ".join(str(exc).split())


def _input_error(exc: Exception) -> bool:
    """An error in what the user gave (a spec or log field, an unknown name, a method scored on its own calibration
    run, nothing to score): one line, exit 2.  bench.registry and bench.metrics are imported only here, when a
    command has failed, not at every start-up (bench.metrics pulls in scipy: 0.2 s)."""
    if isinstance(exc, (SpecError, RunError, KeyError)):
        return True
    if isinstance(exc, OSError) and exc.filename is not None:  # an output path that is a folder, a missing file ...
        return True
    from bench.metrics.trajectory import MetricError
    from bench.real.benchmark import NoWindowModels
    from bench.registry import CalibrationDataError, CalibrationLeak, PluginLoadError

    return isinstance(exc, (CalibrationLeak, CalibrationDataError, MetricError, NoWindowModels, PluginLoadError))


if __name__ == "__main__":
    # run through the imported module so that commands registered by bench.cli.<group> land in the
    # same COMMANDS table (``python -m bench.cli`` would otherwise have two copies of this module)
    from bench.cli import main as _main

    sys.exit(_main())
