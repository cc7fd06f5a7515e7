"""One reproduce, one published set of results: the run writes into a staging folder, which replaces the results
folder only when the whole run has finished.

    with staged(results_dir) as stage:   # a copy of results_dir (what this run does not rewrite stays)
        ... write everything into stage ...
    # here stage has replaced results_dir; on an exception (or a kill) results_dir is untouched

Without it, a kill between two writes left a mix of two runs: a paper's tables without ``metrics.json``, or
``metrics.json`` without the ``REPORT.md`` that cites it.  The publication is two renames of sibling folders
(``results`` -> ``.results.old``, ``.results.staging`` -> ``results``), each atomic; a kill between them leaves
``results`` absent, never mixed, and the next run (or :func:`recover`) completes the swap from the staging folder's
``complete`` mark, or puts the old folder back when the mark is missing.  A staging folder left by a killed run is
removed at the next start.

A lock (``flock`` on ``.<name>.lock`` beside the folder that holds the project's results) keeps two reproduces
from writing one results tree at once: the second stops with a one-line error.  The run removes the lock file
before it releases it (a run that opened the removed file finds it gone once it holds it, and opens the path again),
so no lock file is left beside the folder.  ``results/quick/`` and
``results/extended/`` lock ``results/`` too, since publishing ``results/`` moves them.

A staging folder knows where it will be published (:func:`final_dir`), so what depends on the results folder's
name (``history.jsonl`` of ``results/quick/`` lives in ``results/``; the extras' result-cache key) uses the final
folder.
"""
from __future__ import annotations

import fcntl
import json
import os
import shutil
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Iterator

from bench.paths import default_results
from bench.spec import SpecError

__all__ = ["staged", "recover", "final_dir", "ResultsBusy"]

_MARK = ".staging.json"  # in a staging folder: {"final": path, "complete": bool}


class ResultsBusy(SpecError):
    """Another process is writing the same results tree."""


def _siblings(final: Path) -> tuple[Path, Path]:
    return final.parent / f".{final.name}.staging", final.parent / f".{final.name}.old"


def _lock_root(final: Path) -> Path:
    """The folder whose lock covers ``final``: the project's results folder when ``final`` is inside it."""
    root = default_results().resolve()
    return root if final == root or root in final.parents else final


def final_dir(path: Path) -> Path:
    """The folder a staging folder will be published as; any other folder is its own."""
    mark = Path(path) / _MARK
    if mark.is_file():
        try:
            return Path(json.loads(mark.read_text())["final"])
        except (ValueError, KeyError, TypeError):
            pass
    return Path(path)


def _complete(stage: Path) -> bool:
    try:
        return bool(json.loads((stage / _MARK).read_text()).get("complete"))
    except (OSError, ValueError, AttributeError):
        return False


def recover(final: Path) -> None:
    """Finish or undo a publication that a kill interrupted (call with the lock held)."""
    final = Path(final).resolve()
    stage, old = _siblings(final)
    if not final.exists():
        if stage.is_dir() and _complete(stage):
            os.replace(stage, final)  # the new set was complete: publish it
        elif old.is_dir():
            os.replace(old, final)  # it was not: the previous set comes back
    if final.exists():
        (final / _MARK).unlink(missing_ok=True)
    for leftover in (stage, old):
        if leftover.exists():
            shutil.rmtree(leftover)


def _ignore(folder: str, names: list[str]) -> set[str]:
    """Not copied into a staging folder: another run's staging / old folders, locks, temp files."""
    return {n for n in names if n.startswith(".") and n.endswith((".staging", ".old", ".lock", ".tmp"))} | (
        {_MARK} & set(names))


def _open_locked(lock: Path, root: Path) -> IO[str]:
    """``lock`` opened and ``flock``ed, once the file locked is the one at that path: a run ending removes its lock
    file while it still holds it, so one that opened that file meanwhile locks a removed file and opens it again."""
    while True:
        fh = open(lock, "a+")
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            holder = fh.read().strip() or "?"
            fh.close()
            raise ResultsBusy(lock, "<lock>", holder, f"another skidbench reproduce (pid {holder}) is writing "
                              f"{root}; wait for it to finish") from None
        try:
            same = os.path.samestat(os.stat(lock), os.fstat(fh.fileno()))
        except FileNotFoundError:
            same = False
        if same:
            return fh
        fh.close()  # the file was removed (and maybe made again) after this run opened it: lock the current one


@contextmanager
def _locked(final: Path) -> Iterator[None]:
    root = _lock_root(final)
    root.parent.mkdir(parents=True, exist_ok=True)
    lock = root.parent / f".{root.name}.lock"
    fh = _open_locked(lock, root)
    try:
        fh.truncate(0)  # a killed run's pid may be in it
        fh.write(f"{os.getpid()}\n")
        fh.flush()
        yield
    finally:
        lock.unlink(missing_ok=True)  # removed while held: nothing is left beside the results folder
        fh.close()  # closing releases the flock


@contextmanager
def staged(results_dir: Path) -> Iterator[Path]:
    """A staging copy of ``results_dir`` to write the run into, published in its place on normal exit
    (see the module docstring); removed on an exception, the results folder then untouched."""
    final = Path(results_dir).resolve()
    with _locked(final):
        recover(final)
        stage, old = _siblings(final)
        if final.is_dir():
            shutil.copytree(final, stage, symlinks=True, ignore=_ignore)
        else:
            stage.mkdir(parents=True)
        (stage / _MARK).write_text(json.dumps({"final": str(final), "complete": False}))
        try:
            yield stage
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            raise
        (stage / _MARK).write_text(json.dumps({"final": str(final), "complete": True}))
        if final.exists():
            os.replace(final, old)
        os.replace(stage, final)
        (final / _MARK).unlink()
        shutil.rmtree(old, ignore_errors=True)
