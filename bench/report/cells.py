"""Markdown table cells of the reports: at most :data:`CELL_LIMIT` characters each (a longer text is cut and
linked to its whole), and a check that finds the cells over it."""
from __future__ import annotations

import re
from typing import Any

__all__ = ["CELL_LIMIT", "cell", "long_cells"]

CELL_LIMIT = 300


def cell(x: Any, more: str | None = None, limit: int = CELL_LIMIT) -> str:
    """Markdown table cell of at most ``limit`` characters: pipes escaped, whitespace folded; a longer text is cut
    at a sentence (or word) end and, with ``more``, followed by a link to the whole text."""
    s = re.sub(r"\s+", " ", "" if x is None else str(x)).strip().replace("|", "\\|")
    if len(s) <= limit:
        return s
    tail = f" … [more]({more})" if more else " …"
    head = s[:limit - len(tail)]
    stop = max(head.rfind(". "), head.rfind("; "))
    if stop < len(head) // 2:
        stop = head.rfind(" ")
    if stop >= len(head) // 2:  # else one long word: a hard cut
        head = head[:stop + 1]
    if head.count("`") % 2:  # no code span left open
        head = head[:head.rfind("`")]
    return head.rstrip(" \\") + tail


def long_cells(text: str, limit: int = CELL_LIMIT) -> list[str]:
    """The cells of the markdown tables in ``text`` longer than ``limit`` characters."""
    out = []
    for line in text.splitlines():
        if line.startswith("|"):
            out += [c.strip() for c in re.split(r"(?<!\\)\|", line.strip().strip("|")) if len(c.strip()) > limit]
    return out
