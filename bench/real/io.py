"""Atomic outputs of the real-data reports: files written to a temp file then ``os.replace``d (never a
half-written result), PNG figures without wall-clock metadata (same input, same bytes), and a figure
on an Agg canvas (no pyplot global state).  Used by :mod:`bench.real.report` and
:mod:`bench.real.gap_report`."""
from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path
from typing import Any


def _atomic_write_bytes(path: Path, data: bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.chmod(tmp, 0o644)  # mkstemp creates 0600; results are shared files
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def _atomic_write_text(path: Path, text: str) -> Path:
    return _atomic_write_bytes(path, text.encode("utf-8"))


def _save_figure(fig: Any, path: Path) -> Path:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, metadata={"Software": None})
    return _atomic_write_bytes(path, buf.getvalue())


def _new_figure(w: float, h: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)  # Agg canvas, no pyplot global state
    return fig

