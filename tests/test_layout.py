"""The code layout's rules (DESIGN.md "Layout"): the harness never imports a paper, modules stay small,
no grab-bag module names, and each paper is one package that opens with its citation and equation map."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
MAX_LINES = 600
GRAB_BAG = re.compile(r"_(more|misc|utils?)$|^(misc|utils?|helpers?)$")
PAPERS = ("yi2009", "liu2020", "mandow2007", "wang2015", "yu2010")


def methods_imports(source: str, filename: str = "<src>") -> list[tuple[int, str]]:
    """(line, module) of every import of ``methods`` or a submodule in ``source``: ``import methods[.x]``,
    ``from methods[.x] import ...``, and ``importlib.import_module("methods[.x]")`` with a literal name, at any
    depth (inside functions too)."""
    out: list[tuple[int, str]] = []
    for node in ast.walk(ast.parse(source, filename)):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names if a.name.split(".")[0] == "methods"]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            if node.module.split(".")[0] == "methods":
                out.append((node.lineno, node.module))
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", "")) in (
                "import_module", "__import__"):
            arg = node.args[0] if node.args else None
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str) and arg.value.split(".")[0] == "methods":
                out.append((node.lineno, arg.value))
    return out


def _sources(*folders: str) -> list[Path]:
    return sorted(p for f in folders for p in (REPO / f).rglob("*.py"))


@pytest.mark.parametrize("src, found", [
    ("import methods\n", ["methods"]),
    ("from methods.yi2009 import ekf_v1\n", ["methods.yi2009"]),
    ("def f():\n    import methods.liu2020 as L\n    return L\n", ["methods.liu2020"]),
    ("import importlib\nimportlib.import_module('methods.wang2015')\n", ["methods.wang2015"]),
    ("from bench import registry\nimport methodsx\nfrom .methods import y\n", []),
])
def test_the_import_check_finds_what_it_should(src, found):
    assert [m for _, m in methods_imports(src)] == found


def test_bench_never_imports_methods():
    bad = [f"{p.relative_to(REPO)}:{line}: {mod}" for p in _sources("bench")
           for line, mod in methods_imports(p.read_text(), str(p))]
    assert not bad, "the harness imports a paper (take methods by registry name instead):\n" + "\n".join(bad)


def test_no_source_module_is_longer_than_the_limit():
    long = {str(p.relative_to(REPO)): n for p in _sources("bench", "methods", "tests", "benchmarks")
            if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


def test_no_grab_bag_module_names():
    bad = [str(p.relative_to(REPO)) for p in _sources("bench", "methods", "tests") if GRAB_BAG.search(p.stem)]
    assert not bad, f"modules named by accident, not by what they hold: {bad}"


@pytest.mark.parametrize("paper", PAPERS)
def test_each_paper_is_a_package_that_opens_with_its_citation_and_equation_map(paper):
    init = REPO / "methods" / paper / "__init__.py"
    assert init.is_file(), f"methods/{paper}/ is not a package"
    assert not (REPO / "methods" / f"{paper}.py").exists() and not (REPO / "methods" / f"{paper}_repro.py").exists()
    doc = ast.get_docstring(ast.parse(init.read_text())) or ""
    year = paper[-4:]
    assert year in doc.split("\n\n")[0] or year in doc[:400], f"{paper}: the docstring does not open with the citation"
    assert re.search(r"\beq(s?\.|uation)", doc, flags=re.I) and len(re.findall(r"\(\d+[a-z]?\)", doc)) >= 5, \
        f"{paper}: no map from the paper's equations to the code in the docstring"
    module = re.search(r'^module\s*=\s*"([^"]+)"', (REPO / "scenarios" / "papers" / f"{paper}.toml").read_text(), re.M)
    assert module and module.group(1).startswith(f"methods.{paper}."), f"{paper}: the repro module is not in its package"
