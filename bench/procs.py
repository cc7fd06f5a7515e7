"""Process pools whose workers end with their parent: a SIGKILL of ``skidbench reproduce`` (or of any caller) must
not leave its pool workers (~210 MB each) running.  Linux: each worker asks the kernel for SIGTERM when its parent
dies (``prctl(PR_SET_PDEATHSIG)``); elsewhere the pool is a plain one.
"""
from __future__ import annotations

import ctypes
import os
import signal
import sys
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.managers import SyncManager
from typing import Any

__all__ = ["end_with_parent", "process_pool", "queue_manager"]

PR_SET_PDEATHSIG = 1  # linux/prctl.h


def end_with_parent(parent: int | None = None) -> None:
    """Pool initializer: SIGTERM to this worker when its parent process ends; exit at once if it already has."""
    if not sys.platform.startswith("linux"):
        return
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except (OSError, AttributeError):  # no libc prctl: a plain worker
        return
    if parent is not None and os.getppid() != parent:  # the parent died before the request took effect
        os._exit(1)


def process_pool(max_workers: int, **kwargs: Any) -> ProcessPoolExecutor:
    """``ProcessPoolExecutor(max_workers, **kwargs)`` whose workers end with the process that made the pool."""
    return ProcessPoolExecutor(max_workers=max_workers, initializer=end_with_parent, initargs=(os.getpid(),), **kwargs)


def queue_manager() -> SyncManager:
    """A started :class:`multiprocessing.managers.SyncManager` (its ``Queue()`` proxies can be passed to pool jobs)
    whose server process ends with this one, like the pools' workers.  Use as a context manager."""
    manager = SyncManager()
    manager.start(end_with_parent, (os.getpid(),))
    return manager
