"""Pool workers end with their parent: SIGKILL of the process that made the pool leaves no worker behind, nor the
server process of the queue manager that carries reproduce's progress events (bench.procs.queue_manager)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

SCRIPT = """
import os, sys, time
from bench.procs import process_pool, queue_manager

def pid(_):
    time.sleep(0.2)
    return os.getpid()

if __name__ == "__main__":
    ex = process_pool(2)
    pids = sorted(set(ex.map(pid, range(4))))
    ex.submit(time.sleep, 600)  # a worker busy when the parent dies
    manager = queue_manager()
    print(" ".join(map(str, pids + [manager._process.pid])), flush=True)
    time.sleep(600)
"""


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split()[2] != "Z"  # a zombie has ended
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="prctl(PR_SET_PDEATHSIG) is Linux's")
def test_workers_end_when_their_parent_is_killed(tmp_path) -> None:
    script = tmp_path / "parent.py"
    script.write_text(SCRIPT)
    p = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True,
                         env={**os.environ, "PYTHONPATH": os.getcwd()})
    try:
        workers = [int(x) for x in p.stdout.readline().split()]
        assert workers and all(_alive(w) for w in workers)
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        deadline = time.monotonic() + 30  # a bound on the wait, not a speed check: the kernel signals at once
        while any(_alive(w) for w in workers) and time.monotonic() < deadline:
            time.sleep(0.05)
        left = [w for w in workers if _alive(w)]
        for w in left:
            os.kill(w, signal.SIGKILL)
        assert not left, f"workers {left} outlived their parent"
    finally:
        if p.poll() is None:
            p.kill()


def test_a_plain_pool_would_leave_them(tmp_path) -> None:
    """The same script with concurrent.futures' own pool: the killed parent's workers stay (what the test guards)."""
    if not sys.platform.startswith("linux"):
        pytest.skip("Linux only")
    script = tmp_path / "parent.py"
    script.write_text(SCRIPT.replace("from bench.procs import process_pool, queue_manager",
                                     "from concurrent.futures import ProcessPoolExecutor as process_pool\n"
                                     "from multiprocessing import Manager as queue_manager"))
    p = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True)
    workers = [int(x) for x in p.stdout.readline().split()]
    os.kill(p.pid, signal.SIGKILL)
    p.wait()
    time.sleep(1.0)
    left = [w for w in workers if _alive(w)]
    for w in left:
        os.kill(w, signal.SIGKILL)
    assert left, "plain ProcessPoolExecutor workers ended with their parent: the guarded defect is gone here"
