"""What a result is tied to: the git commit (``+dirty`` for uncommitted changes), the package versions,
and :func:`code_key`, the hash of everything a paper's result depends on (the key of the result cache).
"""
from __future__ import annotations

import hashlib
import importlib.util
import json
import os
import platform as _platform
import subprocess
from importlib.machinery import EXTENSION_SUFFIXES
from pathlib import Path

from bench.reproduce.runner import REPO

__all__ = ["code_key", "compiled_extensions", "git_commit", "package_versions"]


# say where caches and scenario files are, not what a result is (the scenario files' contents are hashed)
_WHERE_ONLY = ("SKIDBENCH_CACHE", "SKIDBENCH_TEST_CACHE", "SKIDBENCH_SCENARIOS")


def code_key(*extra: str) -> str:
    """Hash of everything a result depends on: the source of bench/ and methods/, the scenario,
    platform, terrain and paper files (of :data:`bench.paths.SCENARIO_DIR`), the installed package versions, which C extensions run
    (:func:`compiled_extensions`), plus ``extra``."""
    from bench.paths import SCENARIO_DIR

    h = hashlib.sha256()
    for folder, pattern in (("bench", "**/*.py"), ("bench", "**/*.c"), ("methods", "**/*.py"), ("methods", "**/*.c")):
        for p in sorted((REPO / folder).glob(pattern)):
            h.update(str(p.relative_to(REPO)).encode())
            h.update(p.read_bytes())
    for p in sorted(SCENARIO_DIR.glob("**/*.toml")):  # the checkout's, the installed package's or SKIDBENCH_SCENARIOS
        h.update(("scenarios/" + p.relative_to(SCENARIO_DIR).as_posix()).encode())
        h.update(p.read_bytes())
    h.update(json.dumps(package_versions(), sort_keys=True).encode())
    h.update(json.dumps(compiled_extensions(), sort_keys=True).encode())
    h.update(json.dumps(sorted((k, v) for k, v in os.environ.items() if k.startswith("SKIDBENCH_")
                               and k not in _WHERE_ONLY)).encode())
    for e in extra:
        h.update(e.encode())
    return h.hexdigest()[:24]


def compiled_extensions(root: Path = REPO) -> dict[str, str]:
    """The C extensions of bench/ and methods/ and what runs: ``{module: state}``, the state "built", "not built" (a
    ``.c`` without a module this interpreter loads: the Python reference runs), "fails to load" (the code falls back
    to its Python reference too), "stale" (built, then its ``.c`` changed: the old build runs) or "off" (built, but
    ``SKIDBENCH_KERNEL=python`` runs the reference).  A module is loaded from its file to test it, never imported by
    name.  Part of the result's identity: the testbed's step is the same bits either way, but Mandow's C cost is not
    (its sums run in order, numpy's pairwise), and the DE polish carries that last bit to the 5th digit of the
    league's DE row (README, "The testbed's C step")."""
    suffixes = sorted(EXTENSION_SUFFIXES, key=len, reverse=True)
    off = os.environ.get("SKIDBENCH_KERNEL", "c") == "python"
    found: dict[str, str] = {}
    for folder in ("bench", "methods"):
        for p in sorted((root / folder).rglob("*")):
            rel = p.relative_to(root).as_posix()
            if rel.endswith(".c"):
                found.setdefault(rel[:-2].replace("/", "."), "not built")
                continue
            suffix = next((s for s in suffixes if rel.endswith(s)), None)
            if suffix is None or "." in p.name[:-len(suffix)]:
                continue
            module = rel[:-len(suffix)].replace("/", ".")
            source = p.with_name(p.name[:-len(suffix)] + ".c")
            if off:
                found[module] = "off"
            elif not _loads(p, module):
                found[module] = "fails to load"
            elif source.is_file() and source.stat().st_mtime > p.stat().st_mtime:
                found[module] = "stale"
            else:
                found[module] = "built"
    return dict(sorted(found.items()))


def _loads(path: Path, module: str) -> bool:
    """Whether the extension module at ``path`` loads in this interpreter (as its import would)."""
    spec = importlib.util.spec_from_file_location(module, path)
    try:
        importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    except (ImportError, OSError):
        return False
    return True


def git_commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--", ".", ":!results"], cwd=REPO,
                               capture_output=True, text=True).stdout.strip()
        return out.stdout.strip() + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"  # (results/ itself is excluded from the dirty check: reproduce writes it)


def code_differs(a: str, b: str, repo: Path = REPO) -> bool | None:
    """Whether commits ``a`` and ``b`` differ outside ``results/`` (a "+dirty" mark counts as a difference); None
    when git cannot tell (no repository, an unknown commit)."""
    if not a or not b or "unknown" in (a, b):  # git_commit() could not tell: nothing to compare
        return None
    if "dirty" in a or "dirty" in b:
        return True
    if a == b:
        return False
    try:
        out = subprocess.run(["git", "diff", "--name-only", a, b, "--", ".", ":!results"], cwd=repo,
                             capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    return bool(out.stdout.strip())


def package_versions() -> dict[str, str]:
    from importlib import metadata

    out = {"python": _platform.python_version()}
    for pkg in ("numpy", "scipy", "pandas", "pyarrow", "pybullet", "matplotlib", "pygad", "filterpy"):
        try:
            out[pkg] = metadata.version(pkg)
        except metadata.PackageNotFoundError:
            pass
    return out
