"""Loading a DRIVE pickle without running its code: an unpickler that rebuilds numpy and pandas objects alone.

DRIVE (Baril et al., ICRA 2024) publishes its window tables as pandas pickles.  ``pandas.read_pickle`` runs whatever
the file names: a pickle's GLOBAL / STACK_GLOBAL opcodes import any callable (``os.system``, ``subprocess.Popen``)
and its REDUCE opcode calls it.  Every global a pickle uses goes through :meth:`pickle.Unpickler.find_class` (the
"restricting globals" recipe of the :mod:`pickle` documentation), so :class:`TableUnpickler` lets through only the
reconstructors numpy, pandas and pyarrow write for a DataFrame (:data:`ALLOWED`: measured on pandas 3.1 / numpy 2.4
with protocols 2-5, plus the module paths of earlier releases) and refuses any other before anything is called.
"""
from __future__ import annotations

import io
import pickle
from pathlib import Path
from typing import Any

from bench.run import RunError

__all__ = ["ALLOWED", "TableUnpickler", "load_table_pickle"]

_BUILTINS = {"slice", "bytearray", "set", "frozenset", "complex", "range", "list", "dict", "tuple", "int", "float",
             "str", "bytes", "bool"}
_PANDAS_OBJECTS = {"DataFrame", "Series", "Index", "RangeIndex", "MultiIndex", "Categorical", "CategoricalDtype",
                   "StringDtype", "DatetimeTZDtype", "Timestamp", "Timedelta", "DatetimeIndex", "CategoricalIndex"}
_PANDAS_ARRAYS = {"ArrowStringArray", "DatetimeArray", "TimedeltaArray", "BooleanArray", "IntegerArray",
                  "FloatingArray", "StringArray", "ArrowExtensionArray"}
#: (module, name) pairs a DataFrame pickle may rebuild
ALLOWED: frozenset[tuple[str, str]] = frozenset(
    {(m, n) for m in ("builtins", "__builtin__") for n in _BUILTINS}
    | {("_codecs", "encode"), ("copyreg", "_reconstructor"), ("collections", "OrderedDict"), ("datetime", "datetime"),
       ("datetime", "timedelta"), ("numpy", "dtype"), ("numpy", "ndarray")}
    | {(f"numpy.{core}.{mod}", n) for core in ("core", "_core")
       for mod, n in (("multiarray", "_reconstruct"), ("multiarray", "scalar"), ("numeric", "_frombuffer"))}
    | {("pandas", n) for n in _PANDAS_OBJECTS} | {("pandas.arrays", n) for n in _PANDAS_ARRAYS}
    | {("pandas.core.frame", "DataFrame"), ("pandas.core.series", "Series"),
       ("pandas.core.indexes.base", "_new_Index"), ("pandas.core.indexes.base", "Index"),
       ("pandas.core.indexes.range", "RangeIndex"), ("pandas.core.indexes.multi", "MultiIndex"),
       ("pandas.core.internals.managers", "BlockManager"), ("pandas.core.internals.managers", "SingleBlockManager"),
       ("pandas.core.internals.blocks", "new_block"), ("pandas._libs.internals", "_unpickle_block"),
       ("pandas._libs.arrays", "__pyx_unpickle_NDArrayBacked"),
       ("pandas._libs.tslibs.timestamps", "_unpickle_timestamp"),
       ("pandas._libs.tslibs.timedeltas", "_timedelta_unpickle"),
       ("pandas.core.arrays.categorical", "Categorical"), ("pandas.core.arrays.datetimes", "DatetimeArray"),
       ("pandas.core.arrays.string_", "StringArray"), ("pandas.core.arrays.string_", "StringDtype"),
       ("pandas.core.arrays.string_arrow", "ArrowStringArray"),
       ("pandas.core.dtypes.dtypes", "CategoricalDtype"), ("pandas.core.dtypes.dtypes", "DatetimeTZDtype"),
       ("pyarrow.lib", "_restore_array"), ("pyarrow.lib", "py_buffer"), ("pyarrow.lib", "type_for_alias")}
    | {("numpy.dtypes", f"{k}DType") for k in ("Float64", "Float32", "Int64", "Int32", "Int16", "Int8", "UInt64",
                                               "UInt32", "UInt16", "UInt8", "Bool", "Object", "Str", "Bytes",
                                               "DateTime64", "TimeDelta64")})


class RefusedGlobal(pickle.UnpicklingError):
    def __init__(self, module: str, name: str) -> None:
        self.module, self.name = module, name
        super().__init__(f"{module}.{name}")


class TableUnpickler(pickle.Unpickler):
    """An unpickler whose globals are :data:`ALLOWED` alone (others raise :class:`RefusedGlobal`)."""

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) not in ALLOWED:
            raise RefusedGlobal(module, name)
        return super().find_class(module, name)


def load_table_pickle(path: Path) -> Any:
    """The DataFrame of a DRIVE pickle, or a one-line :class:`~bench.run.RunError` naming the refused global."""
    import pandas as pd

    data = Path(path).read_bytes()
    try:
        obj = TableUnpickler(io.BytesIO(data)).load()
    except RefusedGlobal as exc:
        raise RunError(str(path), "<pickle>", f"{exc.module}.{exc.name}",
                       "refused: this pickle calls a function other than the numpy/pandas reconstructors of a table "
                       "(a pickle can run any code); convert the table to Parquet where it was made") from None
    except Exception as exc:  # noqa: BLE001 - a truncated or foreign file is a bad input
        raise RunError(str(path), "<pickle>", type(exc).__name__, f"not a readable pickle ({exc})") from None
    if not isinstance(obj, pd.DataFrame):
        raise RunError(str(path), "<pickle>", type(obj).__name__, "expected a pandas DataFrame (a DRIVE window table)")
    return obj
