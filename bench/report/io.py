"""Atomic file writes: everything under results/ is written to a temp file and renamed, so an
interrupted run leaves either the old file or the new one, never half of one.

JSON is written strict (RFC 8259, readable by any JSON parser): a non-finite float is written as
null (NaN: "no value", e.g. the ICR of a straight line) or as the string "inf" / "-inf";
:func:`json_number` reads all three back, and :func:`bench.spec.build` accepts the strings in a
float field (``command_limit_mean = inf``: no limit)."""
from __future__ import annotations

import errno
import json
import math
import numbers
import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Iterator


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temp path beside ``path``; on success rename it over ``path``, else delete it.  A ``path`` that is a
    folder is refused first (an OSError naming it: one line at the command line)."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "a folder, not a file to write", str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; results are meant to be read by others
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def atomic_write_text(path: str | Path, text: str) -> Path:
    with atomic_path(path) as tmp:
        tmp.write_text(text)
    return Path(path)


# the JSON spellings of an infinite float (json_safe writes the first and the last; bench.spec reads them all)
INF_STRINGS = {"inf": math.inf, "+inf": math.inf, "-inf": -math.inf}


def json_safe(obj: Any) -> Any:
    """``obj`` with every non-finite float inside (dicts, lists, tuples) replaced: NaN -> None,
    +inf / -inf -> "inf" / "-inf".  Finite values and other objects are returned unchanged."""
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, numbers.Real) and not isinstance(obj, numbers.Integral) and not math.isfinite(obj):
        return None if math.isnan(obj) else ("inf" if obj > 0 else "-inf")
    return obj


def json_number(value: Any) -> float | None:
    """A number as :func:`dumps_json` wrote it, back as a float: None (null) -> NaN, "inf" / "-inf"
    (or "+inf") -> +-inf, a JSON number (or Python's NaN / Infinity of older files) -> itself.  None if
    ``value`` is not a number at all (a string other than these, a list, ...)."""
    if value is None:
        return math.nan
    if isinstance(value, str):
        return INF_STRINGS.get(value.strip().lower())
    if isinstance(value, numbers.Real):
        return float(value)
    return None


def dumps_json(obj: Any, **kw: Any) -> str:
    """``json.dumps`` of :func:`json_safe` ``(obj)`` with ``allow_nan=False`` (strict JSON) and
    ``default=str`` (paths, numpy scalars)."""
    return json.dumps(json_safe(obj), allow_nan=False, default=str, **kw)


def atomic_write_json(path: str | Path, obj: Any) -> Path:
    return atomic_write_text(path, dumps_json(obj, indent=1, sort_keys=True) + "\n")


def atomic_savefig(fig: Any, path: str | Path, **kw: Any) -> Path:
    """Save a matplotlib figure atomically (format from the final suffix)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png", **kw)
    return path


def jsonl_objects(path: Path, required: tuple[str, ...] = ()) -> list[tuple[int, dict]]:
    """(line number, object) of each non-blank line of a JSON-lines file; a malformed line, a line that is not an
    object or one without a ``required`` key is a :class:`bench.spec.SpecError` naming the file, line and field."""
    from bench.spec import SpecError

    out = []
    for lineno, line in enumerate(Path(path).read_text().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            obj = json.loads(line)
        except ValueError as exc:
            raise SpecError(path, f"line {lineno}", line[:60], f"malformed JSON: {exc}") from None
        if not isinstance(obj, dict):
            raise SpecError(path, f"line {lineno}", line[:60], "a JSON object per line")
        for key in required:
            if key not in obj:
                raise SpecError(path, f"line {lineno}: {key}", None, "required field is missing")
        out.append((lineno, obj))
    return out
