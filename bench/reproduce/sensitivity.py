"""Which verdicts a chosen testbed parameter decides: the papers re-run at each choice's declared alternative.

A parameter of kind ``chosen`` (:mod:`bench.sources`) was set to produce an outcome; the claims it names are
calibration targets, never verdicts.  The same value shapes every other run on that platform or terrain, so a
verdict it was not chosen for may still hang on it.  This study makes that visible (``reproduce --extended``):

1. **Choices.**  The parameters of kind ``chosen`` or ``testbed`` (a value the testbed chose) of the platform and
   terrain files that declare an ``alternative`` (with ``alternative_ref``: why that value, e.g. the value before
   the choice, or the papers' law), grouped by the claims they name, a ``testbed`` choice (no claims) by its
   ``alternative_ref``: parameters chosen together change together (:func:`choices`).
2. **Runs.**  For each choice, the papers whose runs use one of its files (by the platform and terrain names of the
   base run's ``runs_manifest.json``) are reproduced in a child process on a copy of the scenario folder with the
   alternatives written in (``SKIDBENCH_SCENARIOS``; :func:`run_choice`).  The run cache is shared: a run whose
   physics the change does not touch is not simulated again.
3. **Comparison.**  Every claim of those papers whose verdict differs from the base run's (the full run's
   ``claims.json``, normally ``results/claims.json`` of the same commit) is listed with both measurements
   (:func:`flips`).  A calibration target that flips is expected (it was chosen for that); any other flip is a
   verdict that holds or fails at the testbed's choice, not at a published number.

Writes ``sensitivity.md`` and ``sensitivity.json`` in the results folder.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from bench.paths import SCENARIO_DIR, default_results
from bench.report.io import atomic_write_text, dumps_json
from bench.schema import read_toml
from bench.sources import ALTERNATIVE_KINDS, file_sources, parameters

__all__ = ["Edit", "Choice", "choices", "set_value", "papers_using", "run_choice", "flips", "run_sensitivity",
           "base_files"]

FOLDERS = ("platforms", "terrains")


@dataclass(frozen=True)
class Edit:
    """One parameter of a choice: ``file`` relative to the scenario folder, ``key`` as the file writes it."""

    file: str
    key: str
    value: Any
    alternative: Any
    why: str

    @property
    def name(self) -> str:
        return f"{Path(self.file).stem}.{self.key}"


@dataclass(frozen=True)
class Choice:
    """The parameters chosen together (naming the same claims; or, with none, the same alternative), with their
    alternatives."""

    claims: tuple[str, ...]
    edits: tuple[Edit, ...]

    @property
    def name(self) -> str:
        return ", ".join(f"{e.name} = {e.value!r} -> {e.alternative!r}" for e in self.edits)

    @property
    def files(self) -> tuple[str, ...]:
        return tuple(sorted({e.file for e in self.edits}))


def choices(root: Path = SCENARIO_DIR) -> list[Choice]:
    """Every choice of the platform and terrain files under ``root`` that declares alternatives (module doc)."""
    groups: dict[tuple[tuple[str, ...], str], list[Edit]] = {}
    for folder in FOLDERS:
        for path in sorted((Path(root) / folder).glob("*.toml")):
            data = read_toml(path, f"{folder[:-1]} file")
            values = dict(parameters(data))
            for key, src in file_sources(data, path).items():
                if src.kind in ALTERNATIVE_KINDS and src.alternative is not None:
                    group = (tuple(sorted(src.claims)), "" if src.claims else src.alternative_ref)
                    groups.setdefault(group, []).append(
                        Edit(f"{folder}/{path.name}", key, values[key], src.alternative, src.alternative_ref))
    return [Choice(claims, tuple(edits)) for (claims, _), edits in sorted(groups.items())]


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (int, float)):
        return repr(v)
    raise TypeError(f"an alternative must be a number, a string or a boolean, not {type(v).__name__}")


def set_value(text: str, key: str, value: Any) -> str:
    """``text`` (a TOML file) with the parameter ``key`` (dotted: ``motor.max_current`` is ``max_current`` under
    ``[motor]``) set to ``value``; the line's comment is dropped.  Raises KeyError when the file does not write the
    key on a line of its own, ValueError when the result does not read back with the value."""
    *table, leaf = key.split(".")
    section, out, done = "", [], False
    line_re = re.compile(rf"^(\s*){re.escape(leaf)}\s*=")
    for line in text.splitlines(keepends=True):
        head = re.match(r"^\s*\[([^\[\]]+)\]\s*(#.*)?$", line)
        if head:
            section = head.group(1).strip()
        elif not done and section == ".".join(table) and (m := line_re.match(line)):
            line = f"{m.group(1)}{leaf} = {_toml_value(value)}\n"
            done = True
        out.append(line)
    if not done:
        raise KeyError(key)
    new = "".join(out)
    got: Any = tomllib.loads(new)
    for part in key.split("."):
        got = got[part]
    if got != value:
        raise ValueError(f"{key} reads back as {got!r}, not {value!r}")
    return new


def papers_using(choice: Choice, manifest: Mapping[str, Any], papers: Sequence[str], root: Path = SCENARIO_DIR
                 ) -> list[str]:
    """The papers among ``papers`` with a run (``manifest``: a ``runs_manifest.json``) on a platform or terrain
    that ``choice`` changes (matched by the name the file declares, else its stem)."""
    names = set()
    for f in choice.files:
        names.add(str(read_toml(Path(root) / f).get("name", Path(f).stem)))
    used = set()
    for scn in manifest.get("scenarios", {}).values():
        plat, terr = scn.get("platform", {}).get("name"), scn.get("terrain", {}).get("name")
        if scn.get("paper") in papers and (plat in names or terr in names):
            used.add(scn["paper"])
    return sorted(used)


def run_choice(choice: Choice, papers: Sequence[str], workers: int = 1, root: Path = SCENARIO_DIR
               ) -> dict[str, Any]:
    """The ``claims`` of ``claims.json`` of ``reproduce PAPERS`` on a copy of ``root`` with ``choice``'s
    alternatives written in (a child process; the run cache is shared)."""
    with tempfile.TemporaryDirectory(prefix="skidbench-sensitivity-") as tmp:
        scen = Path(tmp) / "scenarios"
        shutil.copytree(root, scen)
        for e in choice.edits:
            p = scen / e.file
            p.write_text(set_value(p.read_text(), e.key, e.alternative))
        out = Path(tmp) / "results"
        env = {**os.environ, "SKIDBENCH_SCENARIOS": str(scen)}
        cmd = [sys.executable, "-m", "bench.cli", "reproduce", *papers, "--results", str(out),
               "--workers", str(max(1, workers))]
        done = subprocess.run(cmd, env=env, capture_output=True, text=True)
        if done.returncode != 0:
            tail = (done.stderr or done.stdout).strip().splitlines()[-1:] or ["(no output)"]
            raise RuntimeError(f"sensitivity run of {choice.name} failed (exit {done.returncode}): {tail[0]}")
        return json.loads((out / "claims.json").read_text())["claims"]


def _outcome(c: Mapping[str, Any]) -> str:
    """A claim's verdict; a calibration target's is what its numbers alone give (its ``holds``)."""
    if c.get("verdict") == "calibration target":
        return f"calibration target ({'holds' if c.get('holds') else 'does not hold'} by the numbers)"
    return str(c.get("verdict"))


def flips(base: Mapping[str, Any], alt: Mapping[str, Any], papers: Sequence[str]) -> list[dict[str, Any]]:
    """The claims of ``papers`` whose verdict (a calibration target's: its numbers' verdict) differs between ``base``
    and ``alt`` (``claims`` of a claims.json)."""
    rows = []
    for key in sorted(alt):
        if key.split(".", 1)[0] not in papers or key not in base:
            continue
        b, a = base[key], alt[key]
        if _outcome(b) != _outcome(a):
            rows.append({"claim": key, "scope": b.get("scope", ""), "headline": bool(b.get("headline")),
                         "base": _outcome(b), "alternative": _outcome(a),
                         "base_measured": b.get("measured", ""), "alternative_measured": a.get("measured", "")})
    return rows


def _markdown(doc: Mapping[str, Any]) -> str:
    lines = ["# Verdicts a testbed choice decides", "",
             "Each choice (the chosen parameters that name the same claims; or testbed values set together, with no "
             "claim in view, that declare the same alternative) is set to its declared alternative and "
             "the papers that run on it are reproduced; a claim is listed when its verdict changes. A calibration "
             "target that changes is what its parameter was chosen for; **any other change is a verdict that holds "
             "or fails at the testbed's choice**, not at a published number "
             "([bench/reproduce/sensitivity.py](../../bench/reproduce/sensitivity.py)).", "",
             f"Base: `{doc['base_file']}` at commit `{doc['base_commit'][:12]}`; this run at `{doc['commit'][:12]}`"
             + {False: "" if doc["base_commit"] == doc["commit"] else " (they differ in results/ only: the same code)",
                True: " (**different code**: a change may be the code's)",
                None: " (**different commits**, not compared here: a change may be the code's)"}[doc.get("code_differs")]
             + ".", ""]
    for c in doc["choices"]:
        files = sorted({e["name"].split(".", 1)[0] for e in c["edits"]})
        lines += [f"## {', '.join(files)}", "", f"Chosen for: {', '.join(c['claims'])}." if c["claims"] else
                  "A testbed choice: no claim in view (kind `testbed`); its alternative is the value below.", ""]
        lines += [f"- `{e['name']}` = {e['value']!r} -> {e['alternative']!r}: {e['why']}" for e in c["edits"]] + [""]
        if not c["papers"]:
            lines += ["No paper runs on these files.", ""]
            continue
        others = [r for r in c["flips"] if not r["target"]]
        lines += [f"Papers re-run: {', '.join(c['papers'])}. Verdicts changed: {len(c['flips'])} "
                  f"({len(others)} not calibration targets).", ""]
        if c["flips"]:
            lines += ["| claim | headline | at the choice | at the alternative | measured at the alternative |",
                      "|---|---|---|---|---|"]
            for r in c["flips"]:
                name = r["claim"] + (" (calibration target)" if r["target"] else "")
                lines.append(f"| {name} | {'yes' if r['headline'] else ''} | {r['base']} | {r['alternative']} | "
                             f"{str(r['alternative_measured'])[:200]} |")
            lines.append("")
    return "\n".join(lines)


def base_files() -> tuple[Path, Path]:
    """The full run the study compares with: ``claims.json`` and ``runs_manifest.json`` of the default results."""
    return default_results() / "claims.json", default_results() / "runs_manifest.json"


def run_sensitivity(results_dir: Path, workers: int = 1, base_file: Path | None = None,
                    root: Path = SCENARIO_DIR) -> dict[str, Any]:
    """The study (module docstring): writes ``sensitivity.md|json`` in ``results_dir``; returns the document."""
    from bench.reproduce.provenance import code_differs, git_commit
    from bench.reproduce.paper import list_papers

    base_file = Path(base_file or base_files()[0])
    base_doc = json.loads(base_file.read_text())
    base = base_doc["claims"]
    manifest = json.loads((base_file.parent / "runs_manifest.json").read_text())
    commit, base_commit = git_commit(), str(base_doc.get("commit", ""))
    doc: dict[str, Any] = {"commit": commit, "base_commit": base_commit, "base_file": base_file.name,
                           "code_differs": code_differs(base_commit, commit), "choices": []}
    for choice in choices(root):
        papers = papers_using(choice, manifest, list_papers(), root)
        rows = flips(base, run_choice(choice, papers, workers, root), papers) if papers else []
        for r in rows:
            r["target"] = r["claim"] in choice.claims or r["base"].startswith("calibration target")
        doc["choices"].append({"name": choice.name, "claims": list(choice.claims), "papers": papers, "flips": rows,
                               "edits": [{"name": e.name, "value": e.value, "alternative": e.alternative,
                                          "why": e.why} for e in choice.edits]})
    results_dir = Path(results_dir)
    atomic_write_text(results_dir / "sensitivity.json", dumps_json(doc) + "\n")
    atomic_write_text(results_dir / "sensitivity.md", _markdown(doc) + "\n")
    return doc
