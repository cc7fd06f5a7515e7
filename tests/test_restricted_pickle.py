"""DRIVE pickles are loaded without running code (bench.real.restricted_pickle): tables pickled by pandas with every
protocol load to the same frame as pandas' own reader; a pickle that calls os.system (or any other global) is
refused with a one-line error before anything runs, from the Python API and through the command line."""
from __future__ import annotations

import os
import pickle

import numpy as np
import pandas as pd
import pytest

from bench.real.drive import import_drive_windows
from bench.real.restricted_pickle import load_table_pickle
from bench.run import RunError


def _frame() -> pd.DataFrame:
    rng = np.random.default_rng(3)
    return pd.DataFrame({"cmd_left_vel": rng.normal(size=5), "steps": np.arange(5), "ok": [True, False] * 2 + [True],
                         "label": list("abcde"), "when": pd.date_range("2024-01-01", periods=5, freq="s"),
                         "kind": pd.Categorical(list("xyxyx"))})


@pytest.mark.parametrize("protocol", [2, 3, 4, 5])
def test_a_pandas_table_pickle_loads_as_pandas_reads_it(tmp_path, protocol):
    path = tmp_path / "t.pkl"
    df = _frame()
    path.write_bytes(pickle.dumps(df, protocol=protocol))
    pd.testing.assert_frame_equal(load_table_pickle(path), pd.read_pickle(path))


class Evil:
    def __init__(self, flag: str) -> None:
        self.flag = flag

    def __reduce__(self):
        return (os.system, (f"touch {self.flag}",))


def test_a_pickle_calling_os_system_is_refused_before_it_runs(tmp_path):
    flag = tmp_path / "ran"
    path = tmp_path / "evil.pkl"
    path.write_bytes(pickle.dumps({"table": _frame(), "payload": Evil(str(flag))}))
    with pytest.raises(RunError, match=r"evil\.pkl.*'<pickle>' = '(posix|os)\.system': refused") as exc:
        load_table_pickle(path)
    assert "\n" not in str(exc.value)
    assert not flag.exists()  # nothing was called
    pickle.loads(path.read_bytes())  # the guarded defect: a plain load runs it
    assert flag.exists()


def test_drive_import_of_an_evil_pickle_is_a_one_line_error_exit_2(tmp_path, capsys):
    from bench.cli import main

    path = tmp_path / "evil.pkl"
    path.write_bytes(pickle.dumps(Evil(str(tmp_path / "ran"))))
    with pytest.raises(RunError, match="refused"):
        import_drive_windows(path)
    assert main(["import-drive", str(path), "--platform", "husky", "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "refused" in err and not (tmp_path / "ran").exists()


def test_a_pickle_of_something_else_than_a_table_is_refused(tmp_path):
    path = tmp_path / "list.pkl"
    path.write_bytes(pickle.dumps([1, 2, 3]))
    with pytest.raises(RunError, match="expected a pandas DataFrame"):
        load_table_pickle(path)
    path.write_bytes(b"\x80\x05not a pickle")
    with pytest.raises(RunError, match="not a readable pickle"):
        load_table_pickle(path)
