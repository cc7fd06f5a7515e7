"""Claims and verdicts: the claim kinds (``ordering | ratio | trend | within | flag``), the metric ids a
claim reads, the per-row verdict of a reproduced number against its published value and tolerance
(``tolerance_abs`` or ``tolerance_rel``; a row of a table ``published_on = "real robot"`` gets the ratio
reproduced / published and no verdict), a claim's evaluation on the computed metrics, the result that would
make it fail (:func:`fails_if`), its verdict (:func:`verdict`) and the checks of a declared claim
(:func:`check_claim`, run by :func:`bench.reproduce.paper.load_paper`).

A claim (``scenarios/papers/<paper>.toml``, ``[[claims]]``)::

    id, text, source               # as before; source names section and page
    quote = "..."                  # the paper's own words, <= 300 characters
    headline = true                # a claim of the abstract / conclusions / main comparative result
    scope = "paper" | "beyond"     # "beyond": our own check (NEES, no NaN, outages), never counted as the paper's
    kind + its fields              # ordering: metrics, margin; ratio: num, den, op, value; trend: series,
                                   # direction, tolerance; within: metric, value, tolerance_abs | tolerance_rel,
                                   # margin;
                                   # flag: metric, expect
    tolerance_origin = "..."       # where a tolerance, margin or threshold other than 1 comes from
    fails_if = "..."               # optional; by default written by :func:`fails_if`
    cause = {kind = "method" | "testbed" | "protocol" | "paper", text = "<= 300 characters"}
    cause_quick = {kind = ..., text = ...}  # optional: the cause shown by a ``--quick`` run (fewer seeds, shorter
                                   # runs: its numbers and its reason may differ); without it the quick run shows cause,
                                   # marked as the full run's (its "of")

A cause text quotes this run's numbers as ``{metric}`` or ``{metric:.3f}`` (a metric ``<table>.<metric>`` of a
declared table, a Python float format; default ``.4g``): :func:`fill_numbers` writes the value in, so a quoted number
does not go stale when the code changes, and a quick run shows its own (the words around it, and any number written
out, stay as declared).  A metric the run did not compute is written ``[no metric id]`` (tests/test_claims.py keeps
it out of the committed results).  A brace outside a quoted metric is an error; the 300-character limit counts each
quoted number at about the longest its format prints.

The words around a quoted number ("loses", "vs", "inside the interval") state relations the numbers may stop
meeting when the code changes.  A cause states them as ``relations = ["a > b", "|a - b| < c", "|a / b - 1| < 0.005"]``
(each side a quoted-style metric id, a number, the ratio ``X / Y`` of two, or ``|X - Y|`` of two of those; ``<``,
``<=``, ``>``, ``>=``; a zero denominator makes the relation stale):
:func:`stale_relations` lists those this run's numbers contradict, the report marks such a cause "stale" and
tests/test_cause_relations.py keeps the committed results free of them.  A cause text that quotes a metric and
uses a comparison word (:data:`COMPARISON_WORDS`) must declare its relations.

An ``ordering`` claim (``metrics = [a, b, ...]``, holds when a < b < ...) may name a ``margin`` metric (e.g. two
standard errors of the difference): it then holds only when a + margin < b at each step, so that an ordering
inside the measurement's sampling error is not reported as holding.  A ``ratio`` claim may name one the same way
(the half-width of the seeds' 95 % interval of the ratio): ``num / den + margin`` must then meet a ``<`` / ``<=``
value (``- margin`` a ``>`` / ``>=`` one).  A ``within`` claim may name one too: its value's interval must then
lie inside the band, ``|metric - value| + margin <= tolerance``.  A failing claim with a margin is *refuted* only when the whole interval
lies on the failing side (:func:`refuted`); when it is not, :func:`favours` says whether the means themselves lie on
the claim's side (it fails only by the interval: the seeds cannot resolve it) or not.  Verdicts are computed from the numbers;
nothing is written by hand: "holds", "does not hold", "calibration target" (a testbed parameter was chosen to
produce the outcome: :mod:`bench.reproduce.sources`), "not evaluated" (a metric is missing or NaN).
"""
from __future__ import annotations

import math
import numbers
import re
from pathlib import Path
from typing import Any, Mapping

from bench.spec import SpecError

__all__ = ["CLAIM_KINDS", "CAUSE_KINDS", "SCOPES", "TEXT_LIMIT", "VERDICTS", "claim_metric_ids", "claim_tables", "row_verdict",
           "row_ratio", "evaluate_claim", "refuted", "favours", "fails_if", "verdict", "check_claim", "needs_tolerance_origin",
           "fill_numbers", "quoted_metrics", "parse_relation", "relation_metrics", "stale_relations", "COMPARISON_WORDS"]

CLAIM_KINDS = ("ordering", "ratio", "trend", "within", "flag")
CAUSE_KINDS = ("method", "testbed", "protocol", "paper")
SCOPES = ("paper", "beyond")
TEXT_LIMIT = 300  # characters of a quote or a cause text (and of any table cell of the report)
VERDICTS = ("holds", "does not hold", "calibration target", "not evaluated")
RATIO_OPS = ("<", "<=", ">", ">=")
DIRECTIONS = ("decreasing", "increasing")
PUBLISHED_ON = ("real robot",)
_KIND_FIELDS = {
    "ordering": ("metrics", "margin"), "ratio": ("num", "den", "op", "value", "margin"),
    "trend": ("series", "direction", "tolerance"), "within": ("metric", "value", "tolerance_abs", "tolerance_rel", "margin"),
    "flag": ("metric", "expect"),
}
_CAUSE_FIELDS = ("kind", "text", "relations")
_COMMON_FIELDS = ("id", "text", "source", "quote", "headline", "scope", "kind", "tolerance_origin", "fails_if",
                  "cause", "cause_quick", "explain_if_fails")


_QUOTED = re.compile(r"\{([A-Za-z0-9_.]+)(?::([^{}]*))?\}")


def quoted_metrics(text: str) -> list[tuple[str, str]]:
    """The ``(metric id, format)`` of each ``{metric}`` / ``{metric:format}`` a cause text quotes (module doc)."""
    return [(m.group(1), m.group(2) or ".4g") for m in _QUOTED.finditer(text)]


def _is_number(v: Any) -> bool:
    """A real number a metric may hold (a bool is a flag, not a number)."""
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def fill_numbers(text: str, metrics: Mapping[str, float]) -> str:
    """``text`` with each quoted metric replaced by its value in ``metrics`` (module doc); a metric the run lacks is
    written ``[no metric id]``, a NaN or infinite one ``[id: nan]`` / ``[id: inf]``."""
    def one(m: re.Match[str]) -> str:
        v = metrics.get(m.group(1))
        if not _is_number(v):
            return f"[no metric {m.group(1)}]"
        if not math.isfinite(v):
            return f"[{m.group(1)}: {v}]"
        return format(v, m.group(2) or ".4g")
    return _QUOTED.sub(one, text)


#: words of a cause text that compare quoted numbers: such a text declares its ``relations`` (module doc)
COMPARISON_WORDS = re.compile(r"\b(vs|loses|wins|beats|favours?|rises|falls|grows|above|below|under|over|lower|higher|"
                              r"less|more|than|smaller|larger|greater|best|worst|lowest|highest|nearer|within|inside|"
                              r"outside|against|cancel|exceeds?)\b|[<>]", re.IGNORECASE)
_ID = r"[A-Za-z_][A-Za-z0-9_.]*"
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_ATOM = rf"(?:{_ID}|{_NUM})"
_VALUE = rf"(?:{_ATOM}(?:\s*/\s*{_ATOM})?)"  # an atom, or the ratio of two
_TERM = rf"(?:\|\s*{_VALUE}\s*-\s*{_VALUE}\s*\||{_VALUE})"
_RELATION = re.compile(rf"^\s*({_TERM})\s*(<=|>=|<|>)\s*({_TERM})\s*$")
_ABS = re.compile(rf"^\|\s*({_VALUE})\s*-\s*({_VALUE})\s*\|$")
_OPS = {"<": lambda a, b: a < b, "<=": lambda a, b: a <= b, ">": lambda a, b: a > b, ">=": lambda a, b: a >= b}


def parse_relation(rel: str) -> tuple[str, str, str] | None:
    """``(left, op, right)`` of a relation ``"a > b"`` / ``"|a - b| < c"`` / ``"|a / b - 1| < 0.005"`` (module doc),
    None when it is not one."""
    m = _RELATION.match(rel) if isinstance(rel, str) else None
    return (m.group(1).strip(), m.group(2), m.group(3).strip()) if m else None


def relation_metrics(rel: str) -> list[str]:
    """The metric ids a relation reads (its atoms that are not numbers)."""
    return [a for a in re.findall(rf"{_NUM}|{_ID}", rel) if not re.fullmatch(_NUM, a)]


def _term_value(term: str, metrics: Mapping[str, float]) -> float | None:
    def atom(a: str) -> float | None:
        a = a.strip()
        if re.fullmatch(_NUM, a):
            return float(a)
        v = metrics.get(a)
        return float(v) if _is_number(v) and math.isfinite(v) else None
    def value(v: str) -> float | None:
        if "/" not in v:
            return atom(v)
        num, den = (atom(a) for a in v.split("/"))
        return None if num is None or den is None or den == 0 else num / den
    if m := _ABS.match(term):
        vx, vy = value(m.group(1)), value(m.group(2))
        return None if vx is None or vy is None else abs(vx - vy)
    return value(term)


def stale_relations(relations: list[str], metrics: Mapping[str, float]) -> list[str]:
    """The relations of a cause (module doc) this run's numbers do not meet, each with the two sides' values
    (``"a > b (0.12 vs 0.15)"``); one whose metric the run lacks is stale too (``n/a``)."""
    stale = []
    for rel in relations:
        left, op, right = parse_relation(rel) or (rel, "<", rel)
        a, b = _term_value(left, metrics), _term_value(right, metrics)
        if a is None or b is None or not _OPS[op](a, b):
            show = ["n/a" if v is None else format(v, ".4g") for v in (a, b)]
            stale.append(f"{rel} ({show[0]} vs {show[1]})")
    return stale


def _longest(spec: str) -> str:
    """The longest of -1.2345678e-05, -1.2345678 and -12.345678 in the format ``spec`` (the length check of a cause
    text as shown: a ``g`` format prints a small number longest; tests/test_claims.py checks the committed results'
    causes as printed)."""
    return max((format(v, spec) for v in (-1.2345678e-05, -1.2345678, -12.345678)), key=len)


def claim_metric_ids(claim: Mapping[str, Any]) -> list[str]:
    """The metric ids a claim reads, by its kind."""
    kind = claim.get("kind")
    if kind == "ordering":
        return list(claim["metrics"]) + ([claim["margin"]] if "margin" in claim else [])
    if kind == "ratio":
        return [claim["num"], claim["den"]] + ([claim["margin"]] if "margin" in claim else [])
    if kind == "trend":
        return list(claim["series"])
    if kind == "within":
        return [claim["metric"]] + ([claim["margin"]] if "margin" in claim else [])
    return [claim["metric"]]


def claim_tables(claim: Mapping[str, Any]) -> set[str]:
    """The ids of the tables whose metrics a claim reads (``<table>.<metric>``)."""
    return {m.split(".")[0] for m in claim_metric_ids(claim)}


def _fmt(x: Any) -> str:
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, (int, float)):
        if isinstance(x, float) and math.isnan(x):
            return "n/a"
        ax = abs(x)
        if ax != 0 and (ax < 1e-3 or ax >= 1e5):
            return f"{x:.3e}"
        return f"{x:.4g}"
    return "n/a" if x is None else str(x)


def _number(x: Any) -> float | None:
    return None if x is None or not isinstance(x, (int, float)) or math.isnan(x) else float(x)


def row_ratio(reproduced: float | None, published: float | None) -> float | None:
    """reproduced / published (None when either is missing or the published value is 0)."""
    rep, pub = _number(reproduced), _number(published)
    return None if rep is None or pub is None or pub == 0 else rep / pub


def row_verdict(reproduced: float | None, row: Mapping[str, Any], published_on: str | None = None) -> str:
    """A table row's verdict: matches / differs within its tolerance; for a number published on a real robot
    the ratio reproduced / published only (never scored)."""
    pub = row.get("published")
    if reproduced is None or (isinstance(reproduced, float) and math.isnan(reproduced)):
        return "not reproduced"
    if pub is None:
        return "—"
    if published_on == "real robot":
        r = row_ratio(reproduced, pub)
        return f"ratio {_fmt(r)} (published on a real robot: not scored)"
    if "tolerance_abs" in row:
        ok = abs(reproduced - pub) <= row["tolerance_abs"]
        return f"{'matches' if ok else 'differs'} (|Δ| {'≤' if ok else '>'} {row['tolerance_abs']})"
    if "tolerance_rel" in row:
        rel = abs(reproduced - pub) / max(abs(pub), 1e-12)
        ok = rel <= row["tolerance_rel"]
        return f"{'matches' if ok else 'differs'} ({rel:.1%} {'≤' if ok else '>'} {row['tolerance_rel']:.1%})"
    return "—"


def _within_tolerance(claim: Mapping[str, Any]) -> tuple[float, str]:
    """(absolute tolerance, its text) of a within claim."""
    target = float(claim["value"])
    if "tolerance_abs" in claim:
        return float(claim["tolerance_abs"]), f"± {claim['tolerance_abs']}"
    tol = float(claim.get("tolerance_rel", 0.1))
    return tol * abs(target), f"± {tol:.0%}"


def _labels(ids: list[str]) -> list[str]:
    """Short names of metric ids: the last component, or as many trailing components as make them distinct
    (``motion.gmean.mi_ukf.yaw_rms`` / ``motion.gmean.ukf_icr.yaw_rms`` -> ``mi_ukf.yaw_rms`` / ``ukf_icr.yaw_rms``)."""
    parts = [m.split(".") for m in ids]
    for n in range(1, max(len(p) for p in parts) + 1):
        labels = [".".join(p[-n:]) for p in parts]
        if len(set(labels)) == len(set(ids)):
            return labels
    return list(ids)


def _margin(claim: Mapping[str, Any], metrics: Mapping[str, float]) -> float:
    """The claim's ``margin`` metric (a half-width of an interval), 0 without one; a negative one, a defect of its
    metric, is taken as 0 and never widens the claim."""
    return max(_number(metrics.get(claim["margin"])), 0.0) if "margin" in claim else 0.0


def evaluate_claim(claim: Mapping[str, Any], metrics: Mapping[str, float]) -> tuple[bool | None, str]:
    """(holds, measured-numbers text). ``None`` when a metric is missing or NaN."""
    def get(mid: str) -> float | None:
        return _number(metrics.get(mid))

    kind = claim["kind"]
    if kind not in CLAIM_KINDS:
        raise ValueError(f"unknown claim kind {kind}")
    absent = [m for m in claim_metric_ids(claim) if get(m) is None]
    if absent:
        return None, f"no value (missing or NaN): {', '.join(absent)}"
    if kind == "ordering":  # a < b < ...; with "margin" (a metric, e.g. 2 standard errors): a + margin < b ...
        ids = claim["metrics"]
        vals = [get(m) for m in ids]
        margin = _margin(claim, metrics)
        ok = all(a + margin < b for a, b in zip(vals, vals[1:]))
        text = " < ".join(f"{name} = {_fmt(v)}" for name, v in zip(_labels(list(ids)), vals))
        if "margin" in claim:
            text += f" by more than {claim['margin'].split('.')[-1]} = {_fmt(margin)}"
        return ok, text
    if kind == "ratio":
        n, d = get(claim["num"]), get(claim["den"])
        if d == 0:
            return None, f"{claim['den'].split('.')[-1]} = 0: no ratio"
        r = n / d
        op, val = claim.get("op", "<="), float(claim["value"])
        margin = _margin(claim, metrics)
        past = r + margin if op in ("<", "<=") else r - margin  # the ratio's interval end nearest the value
        ok = {"<": past < val, "<=": past <= val, ">": past > val, ">=": past >= val}[op]
        num, den = _labels([claim["num"], claim["den"]])
        by = f" by more than {claim['margin'].split('.')[-1]} = {_fmt(margin)}" if "margin" in claim else ""
        return ok, f"{num} / {den} = {_fmt(n)} / {_fmt(d)} = {_fmt(r)} (claim: {op} {val}{by})"
    if kind == "trend":
        vals = [get(m) for m in claim["series"]]
        tol = float(claim.get("tolerance", 0.0))
        sign = -1 if claim.get("direction", "decreasing") == "decreasing" else 1
        ok = all(sign * (b - a) >= -tol for a, b in zip(vals, vals[1:])) and sign * (vals[-1] - vals[0]) > 0
        return ok, "series: " + ", ".join(_fmt(v) for v in vals) + f" ({claim.get('direction', 'decreasing')}, tolerance {tol})"
    if kind == "within":
        v = get(claim["metric"])
        target = float(claim["value"])
        tol, tol_text = _within_tolerance(claim)
        margin = _margin(claim, metrics)
        by = f" (its interval ± {claim['margin'].split('.')[-1]} = {_fmt(margin)} must lie inside the band)" \
            if "margin" in claim else ""
        return abs(v - target) + margin <= tol, f"{_fmt(v)} vs {target} {tol_text}{by}"
    if kind == "flag":
        v = get(claim["metric"])
        return bool(v) == bool(claim.get("expect", True)), f"{claim['metric'].split('.')[-1]} = {_fmt(bool(v))}"
    raise ValueError(f"unknown claim kind {kind}")


def refuted(claim: Mapping[str, Any], metrics: Mapping[str, float]) -> bool | None:
    """For a failing claim with a ``margin`` (the seeds' 95 % interval): True when the interval lies wholly on the
    failing side (an ordering: ``a - margin > b`` at some step; a ratio: ``num / den - margin`` past a ``<`` / ``<=``
    value, ``+ margin`` short of a ``>`` / ``>=`` one; a within: ``|metric - value| - margin`` beyond the
    tolerance), False when the bound lies inside it (the seeds cannot tell:
    not refuted).  None when the claim holds, is not evaluated or has no margin (no interval to read)."""
    holds, _ = evaluate_claim(claim, metrics)
    if holds is not False or "margin" not in claim or claim["kind"] not in ("ordering", "ratio", "within"):
        return None
    m = _margin(claim, metrics)
    if claim["kind"] == "within":  # the whole interval outside the band
        tol, _ = _within_tolerance(claim)
        return abs(_number(metrics.get(claim["metric"])) - float(claim["value"])) - m > tol
    if claim["kind"] == "ordering":
        vals = [_number(metrics.get(x)) for x in claim["metrics"]]
        return any(a - m > b for a, b in zip(vals, vals[1:]))
    r = _number(metrics.get(claim["num"])) / _number(metrics.get(claim["den"]))
    val = float(claim["value"])
    return r - m > val if claim.get("op", "<=") in ("<", "<=") else r + m < val


def favours(claim: Mapping[str, Any], metrics: Mapping[str, float]) -> bool | None:
    """For a failing claim with a ``margin``: True when the point values alone (margin 0) are on the claim's side,
    so that it fails only by the seeds' interval; False when they are against it.  None when the claim holds, is
    not evaluated or has no margin."""
    holds, _ = evaluate_claim(claim, metrics)
    if holds is not False or "margin" not in claim or claim["kind"] not in ("ordering", "ratio", "within"):
        return None
    return evaluate_claim({k: v for k, v in claim.items() if k != "margin"}, metrics)[0]


_NEGATED = {"<": ">=", "<=": ">", ">": "<=", ">=": "<"}


def fails_if(claim: Mapping[str, Any]) -> str:
    """The result that would make the claim fail, from its kind and numbers (a missing or NaN metric is
    "not evaluated", never a failure)."""
    kind = claim["kind"]
    if kind == "ordering":
        ids = list(claim["metrics"])
        m = f" + {claim['margin']}" if "margin" in claim else ""
        steps = [f"{a}{m} >= {b}" for a, b in zip(ids, ids[1:])]
        return " or ".join(steps) + (" (at some step)" if len(steps) > 1 else "")
    if kind == "ratio":
        op = claim.get("op", "<=")
        m = "" if "margin" not in claim else f" {'+' if op in ('<', '<=') else '-'} {claim['margin']}"
        return f"{claim['num']} / {claim['den']}{m} {_NEGATED[op]} {float(claim['value']):g}"
    if kind == "trend":
        series, tol = list(claim["series"]), float(claim.get("tolerance", 0.0))
        decreasing = claim.get("direction", "decreasing") == "decreasing"
        step = "rises" if decreasing else "falls"
        end = f"{series[-1]} {'>=' if decreasing else '<='} {series[0]}"
        by = f" by more than {tol:g}" if tol > 0 else ""
        return f"a step of the series {step}{by}, or {end}"
    if kind == "within":
        target = float(claim["value"])
        tol, _ = _within_tolerance(claim)
        m = f" (+- {claim['margin']})" if "margin" in claim else ""
        return f"{claim['metric']}{m} reaches outside [{target - tol:.6g}, {target + tol:.6g}]" if m else \
            f"{claim['metric']} outside [{target - tol:.6g}, {target + tol:.6g}]"
    if kind == "flag":
        return f"{claim['metric']} is {'false (0)' if claim.get('expect', True) else 'true (non-zero)'}"
    raise ValueError(f"unknown claim kind {kind}")


def verdict(holds: bool | None, calibration: list[str] | tuple[str, ...] = ()) -> str:
    """The verdict of a claim: a missing metric is "not evaluated"; a claim a testbed parameter was chosen for
    is a "calibration target" whatever its numbers; else "holds" / "does not hold"."""
    if holds is None:
        return "not evaluated"
    if calibration:
        return "calibration target"
    return "holds" if holds else "does not hold"


def needs_tolerance_origin(claim: Mapping[str, Any]) -> str | None:
    """The field that makes a claim need a ``tolerance_origin`` (a tolerance, margin or a threshold other than a
    plain comparison with 1), or None."""
    kind = claim.get("kind")
    if kind in ("ordering", "ratio", "within") and "margin" in claim:
        return "margin"
    if kind == "ratio" and float(claim.get("value", 1.0)) != 1.0:
        return "value"
    if kind == "trend" and float(claim.get("tolerance", 0.0)) != 0.0:
        return "tolerance"
    if kind == "within":
        for f in ("tolerance_abs", "tolerance_rel"):
            if f in claim:
                return f if float(claim[f]) != 0.0 else None
        return "tolerance_rel"  # the implicit 10 %
    return None


def _short(text: Any) -> str:
    s = str(text)
    return s if len(s) <= 60 else f"{s[:57]}... ({len(s)} characters)"


def check_claim(path: str | Path, i: int, c: Mapping[str, Any], table_ids: list[str]) -> list[str]:
    """Check one declared claim: raises :class:`SpecError` (file, ``claims.<id>.<field>``, value) on an error;
    returns warnings.  Errors: a missing id, an unknown kind, scope, op, direction, cause kind (``implementation``
    is refused: a defect is fixed, not reported) or ``published_on``, a quote or cause text over 300 characters (as
    shown), a metric (claimed or quoted in a cause) of an undeclared table, a bad quoted format or a stray brace, a
    headline claim of scope "beyond".  The requirements of the new schema (a ``tolerance_origin`` beside a tolerance,
    an explicit tolerance of a within claim, known field names) are errors for a claim that sets ``headline``
    (converted) and warnings for one that does not yet."""
    cid = c.get("id")
    if not isinstance(cid, str) or not cid:
        raise SpecError(path, f"claims[{i}].id", cid, "every claim needs an id (a string)")

    def err(fieldname: str, value: Any, expected: str) -> SpecError:
        return SpecError(path, f"claims.{cid}.{fieldname}", value, expected)

    kind = c.get("kind")
    if kind not in CLAIM_KINDS:
        raise err("kind", kind, f"one of {CLAIM_KINDS}")
    scope = c.get("scope", "paper")
    if scope not in SCOPES:
        raise err("scope", scope, f"one of {SCOPES}")
    if "headline" in c and not isinstance(c["headline"], bool):
        raise err("headline", c["headline"], "true or false")
    if c.get("headline") and scope != "paper":
        raise err("scope", scope, "a headline claim is the paper's: scope must be \"paper\"")
    for f in ("text", "quote", "source", "tolerance_origin", "fails_if"):
        if f in c and not isinstance(c[f], str):
            raise err(f, c[f], "a string")
    if len(c.get("quote", "")) > TEXT_LIMIT:
        raise err("quote", _short(c["quote"]), f"at most {TEXT_LIMIT} characters (the paper's own words, verbatim)")
    for key in ("cause", "cause_quick"):
        if key not in c:
            continue
        cause = c[key]
        if not isinstance(cause, Mapping):
            raise err(key, cause, "a table {kind = ..., text = ...}")
        if set(cause) - set(_CAUSE_FIELDS):
            raise err(key, sorted(set(cause) - set(_CAUSE_FIELDS)), f"fields among {_CAUSE_FIELDS}")
        if cause.get("kind") not in CAUSE_KINDS:
            raise err(f"{key}.kind", cause.get("kind"), f"one of {CAUSE_KINDS} (a defect of ours is fixed, not a cause)")
        text = cause.get("text")
        if not isinstance(text, str) or not text.strip():
            raise err(f"{key}.text", text, "a non-empty string")
        for metric, spec in quoted_metrics(text):
            try:
                format(1.0, spec)
            except ValueError:
                raise err(f"{key}.text", f"{{{metric}:{spec}}}", "a quoted metric's format is a Python float "
                          "format (e.g. .3f, .2g)") from None
            if metric.split(".")[0] not in table_ids:
                raise err(f"{key}.text", f"{{{metric}}}", f"a quoted metric '<table>.<metric>' of a declared table "
                          f"{table_ids}")
        relations = cause.get("relations", [])
        if not isinstance(relations, list):
            raise err(f"{key}.relations", relations, 'a list of relations, e.g. ["a.x > a.y", "|a.x - a.y| < 0.1"]')
        for rel in relations:
            if parse_relation(rel) is None:
                raise err(f"{key}.relations", rel, "a relation 'X op Y' (op one of <, <=, >, >=; X, Y a metric id, "
                          "a number, A / B or |A - B|)")
            read = relation_metrics(rel)
            if not read:
                raise err(f"{key}.relations", rel, "a relation that reads a metric of the run (numbers alone are "
                          "checked once, here, and never go stale)")
            for metric in read:
                if metric.split(".")[0] not in table_ids:
                    raise err(f"{key}.relations", rel, f"metrics '<table>.<metric>' of a declared table {table_ids}")
        words = _QUOTED.sub("", text)  # the text without its quoted metrics
        if quoted_metrics(text) and not relations and (w := COMPARISON_WORDS.search(words)):
            raise err(f"{key}.relations", None, f"the text quotes a metric and compares (\"{w.group(0)}\"): state "
                      "the relations its words claim, checked on every run")
        shown = len(_QUOTED.sub(lambda m: _longest(m.group(2) or ".4g"), text))
        if shown > TEXT_LIMIT:
            raise err(f"{key}.text", _short(text), f"at most {TEXT_LIMIT} characters as shown, not {shown}")
        if set("{}") & set(words):
            raise err(f"{key}.text", _short(text), "braces only around a quoted metric: {metric} or {metric:.3f}")
    try:
        ids = claim_metric_ids(c)
    except KeyError as exc:
        raise err(exc.args[0], None, f"a {kind} claim needs {_KIND_FIELDS[kind]}") from None
    for mid in ids:
        if not isinstance(mid, str) or mid.split(".")[0] not in table_ids:
            raise SpecError(path, f"claims[{i}]", mid, f"claim '{cid}': a metric '<table>.<metric>' of a declared "
                            f"table {table_ids}")
    if kind == "ratio":
        if c.get("op", "<=") not in RATIO_OPS:
            raise err("op", c.get("op"), f"one of {RATIO_OPS}")
        if not isinstance(c.get("value"), (int, float)) or isinstance(c.get("value"), bool):
            raise err("value", c.get("value"), "a number")
    if kind == "trend":
        if c.get("direction", "decreasing") not in DIRECTIONS:
            raise err("direction", c.get("direction"), f"one of {DIRECTIONS}")
        if len(c["series"]) < 2:
            raise err("series", c["series"], "at least two metrics")
    if kind == "ordering" and len(c["metrics"]) < 2:
        raise err("metrics", c["metrics"], "at least two metrics")
    if kind == "within" and (not isinstance(c.get("value"), (int, float)) or isinstance(c.get("value"), bool)):
        raise err("value", c.get("value"), "a number")

    problems: list[tuple[str, Any, str]] = []
    if scope == "paper" and "tolerance_origin" not in c and (f := needs_tolerance_origin(c)):
        problems.append(("tolerance_origin", None, f"required beside '{f}' = {c.get(f)!r}: the seeds' 95 % interval "
                         "(name its metric) or the spread the paper reports (quote where)"))
    if kind == "within" and "tolerance_abs" not in c and "tolerance_rel" not in c:
        problems.append(("tolerance_abs", None, "a within claim states its tolerance (tolerance_abs or tolerance_rel)"))
    known = set(_COMMON_FIELDS) | set(_KIND_FIELDS[kind])
    for f in sorted(set(c) - known):
        problems.append((f, c[f], f"not a field of a {kind} claim ({sorted(known)})"))
    if "headline" in c and problems:
        raise err(*problems[0])
    return [str(err(*p)) for p in problems]


def check_published_on(path: str | Path, tab: Mapping[str, Any]) -> None:
    if "published_on" in tab and tab["published_on"] not in PUBLISHED_ON:
        raise SpecError(path, f"tables.{tab.get('id')}.published_on", tab["published_on"], f"one of {PUBLISHED_ON}")
