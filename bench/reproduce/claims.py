"""Claims and verdicts: the claim kinds (``ordering | ratio | trend | within | flag``), the metric ids a
claim reads, the per-row verdict of a reproduced number against its published value and tolerance
(``tolerance_abs`` or ``tolerance_rel``), and a claim's evaluation on the computed metrics.

An ``ordering`` claim (``metrics = [a, b, ...]``, holds when a < b < ...) may name a ``margin`` metric (e.g. two
standard errors of the difference): it then holds only when a + margin < b at each step, so that an ordering
inside the measurement's sampling error is not reported as holding.  Verdicts are computed from the numbers;
nothing is written by hand.
"""
from __future__ import annotations

import math
from typing import Any, Mapping

__all__ = ["CLAIM_KINDS", "claim_metric_ids", "row_verdict", "evaluate_claim"]

CLAIM_KINDS = ("ordering", "ratio", "trend", "within", "flag")


def claim_metric_ids(claim: Mapping[str, Any]) -> list[str]:
    """The metric ids a claim reads, by its kind."""
    kind = claim.get("kind")
    if kind == "ordering":
        return list(claim["metrics"]) + ([claim["margin"]] if "margin" in claim else [])
    if kind == "ratio":
        return [claim["num"], claim["den"]]
    if kind == "trend":
        return list(claim["series"])
    return [claim["metric"]]


def _fmt(x: Any) -> str:
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, float)):
        if x is None or (isinstance(x, float) and math.isnan(x)):
            return "n/a"
        ax = abs(x)
        if ax != 0 and (ax < 1e-3 or ax >= 1e5):
            return f"{x:.3e}"
        return f"{x:.4g}"
    return "n/a" if x is None else str(x)


def row_verdict(reproduced: float | None, row: Mapping[str, Any]) -> str:
    pub = row.get("published")
    if reproduced is None or (isinstance(reproduced, float) and math.isnan(reproduced)):
        return "not reproduced"
    if pub is None:
        return "—"
    if "tolerance_abs" in row:
        ok = abs(reproduced - pub) <= row["tolerance_abs"]
        return f"{'matches' if ok else 'differs'} (|Δ| {'≤' if ok else '>'} {row['tolerance_abs']})"
    if "tolerance_rel" in row:
        rel = abs(reproduced - pub) / max(abs(pub), 1e-12)
        ok = rel <= row["tolerance_rel"]
        return f"{'matches' if ok else 'differs'} ({rel:.1%} {'≤' if ok else '>'} {row['tolerance_rel']:.1%})"
    return "—"


def evaluate_claim(claim: Mapping[str, Any], metrics: Mapping[str, float]) -> tuple[bool | None, str]:
    """(holds, measured-numbers text). ``None`` when a metric is missing."""
    def get(mid: str) -> float | None:
        v = metrics.get(mid)
        return None if v is None or (isinstance(v, float) and math.isnan(v)) else float(v)

    kind = claim["kind"]
    if kind == "ordering":  # a < b < ...; with "margin" (a metric, e.g. 2 standard errors): a + margin < b ...
        ids = claim["metrics"]
        vals = [get(m) for m in ids]
        margin = get(claim["margin"]) if "margin" in claim else 0.0
        if any(v is None for v in vals) or margin is None:
            return None, "missing metric"
        ok = all(a + margin < b for a, b in zip(vals, vals[1:]))
        text = " < ".join(f"{m.split('.')[-1]} = {_fmt(v)}" for m, v in zip(ids, vals))
        if "margin" in claim:
            text += f" by more than {claim['margin'].split('.')[-1]} = {_fmt(margin)}"
        return ok, text
    if kind == "ratio":
        n, d = get(claim["num"]), get(claim["den"])
        if n is None or d is None or d == 0:
            return None, "missing metric"
        r = n / d
        op, val = claim.get("op", "<="), float(claim["value"])
        ok = {"<": r < val, "<=": r <= val, ">": r > val, ">=": r >= val}[op]
        return ok, f"{claim['num'].split('.')[-1]} / {claim['den'].split('.')[-1]} = {_fmt(n)} / {_fmt(d)} = {_fmt(r)} (claim: {op} {val})"
    if kind == "trend":
        vals = [get(m) for m in claim["series"]]
        if any(v is None for v in vals):
            return None, "missing metric"
        tol = float(claim.get("tolerance", 0.0))
        sign = -1 if claim.get("direction", "decreasing") == "decreasing" else 1
        ok = all(sign * (b - a) >= -tol for a, b in zip(vals, vals[1:])) and sign * (vals[-1] - vals[0]) > 0
        return ok, "series: " + ", ".join(_fmt(v) for v in vals) + f" ({claim.get('direction', 'decreasing')}, tolerance {tol})"
    if kind == "within":
        v = get(claim["metric"])
        if v is None:
            return None, "missing metric"
        target = float(claim["value"])
        if "tolerance_abs" in claim:
            ok = abs(v - target) <= claim["tolerance_abs"]
            return ok, f"{_fmt(v)} vs {target} ± {claim['tolerance_abs']}"
        tol = float(claim.get("tolerance_rel", 0.1))
        ok = abs(v - target) <= tol * abs(target)
        return ok, f"{_fmt(v)} vs {target} ± {tol:.0%}"
    if kind == "flag":
        v = get(claim["metric"])
        if v is None:
            return None, "missing metric"
        return bool(v) == bool(claim.get("expect", True)), f"{claim['metric'].split('.')[-1]} = {_fmt(bool(v))}"
    raise ValueError(f"unknown claim kind {kind}")
