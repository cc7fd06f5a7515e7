"""Where skidbench reads scenarios and writes results and its cache: the checkout's folders, or, installed, the package
data, ./results and the user cache directory (the wheel itself is smoke-tested by .ci/wheel-smoke)."""
from __future__ import annotations

from pathlib import Path

from bench import paths


def test_a_checkout_uses_its_own_folders(monkeypatch) -> None:
    monkeypatch.delenv("SKIDBENCH_CACHE", raising=False)
    assert paths.in_checkout() and paths.SCENARIO_DIR == paths.CHECKOUT / "scenarios"
    assert paths.default_results() == paths.CHECKOUT / "results"
    assert paths.default_cache() == paths.CHECKOUT / ".cache" / "runs"


def test_installed_it_writes_to_the_current_directory_and_the_user_cache(monkeypatch, tmp_path) -> None:
    site = tmp_path / "site-packages"
    (site / "bench").mkdir(parents=True)
    monkeypatch.setattr(paths, "CHECKOUT", site)  # no pyproject.toml / scenarios beside the package
    monkeypatch.delenv("SKIDBENCH_CACHE", raising=False)
    monkeypatch.delenv("SKIDBENCH_DATA", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.chdir(tmp_path)
    assert not paths.in_checkout()
    assert paths.default_results() == tmp_path / "results"
    assert paths.default_cache() == tmp_path / "xdg" / "skidbench" / "runs"
    assert paths.default_data() == tmp_path / "data"
    monkeypatch.setenv("SKIDBENCH_CACHE", str(tmp_path / "c"))
    assert paths.default_cache() == tmp_path / "c"


def test_the_wheel_ships_every_scenario_file() -> None:
    """setup.py's package data covers every file of scenarios/ (all TOML, in the folders it lists)."""
    import ast

    tree = ast.parse((paths.CHECKOUT / "setup.py").read_text())
    listed = next(n.value for n in ast.walk(tree) if isinstance(n, ast.Assign)
                  and any(getattr(t, "id", "") == "SCENARIO_PACKAGES" for t in n.targets))
    pkgs = {ast.literal_eval(e) for e in listed.elts}
    for f in (paths.CHECKOUT / "scenarios").rglob("*"):
        if f.is_file():
            rel = f.relative_to(paths.CHECKOUT / "scenarios")
            pkg = ".".join(("bench", "scenarios", *rel.parts[:-1]))
            assert f.suffix == ".toml" and pkg in pkgs, f"{rel}: not shipped in the wheel"
    assert Path(paths.SCENARIO_DIR).is_dir()
