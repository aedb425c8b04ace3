"""The package's imports run one way (pyproject.toml, [tool.importlinter]):
model | wire | pylaw -> scenario -> results -> sim | emulator | controller |
logs | tools -> export -> live -> hil -> studies -> cli. Checked with import-linter
on the real tree, and shown to catch violations: a copy of the package in
which the plant model imports the CLI, or in which one of the peer packages
(the emulator) imports another (the logs), must break it. Cycles between
modules of one package: tests/test_import_cycles.py."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PKG = ROOT / "python" / "sc_rt"
LINT = str(Path(sys.executable).with_name("lint-imports"))


def _lint(config: Path, cwd: Path, pythonpath: Path) -> subprocess.CompletedProcess:
    return subprocess.run([LINT, "--config", str(config), "--no-cache"], cwd=cwd, capture_output=True,
                          text=True, timeout=120, env={"PYTHONPATH": str(pythonpath), "PATH": "/usr/bin:/bin"})


def _contract_config(tmp: Path, root: str) -> Path:
    """pyproject.toml's contracts, every one, for a copy of the package named ``root``."""
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    text = f"[importlinter]\nroot_package = {root}\n"
    for i, c in enumerate(cfg["contracts"]):
        text += f"\n[importlinter:contract:c{i}]\nname = c{i}\ntype = layers\n"
        if "containers" in c:
            text += "containers =\n" + "".join(f"    {x.replace('sc_rt', root)}\n" for x in c["containers"])
        text += "layers =\n" + "".join(f"    {x.replace('sc_rt', root)}\n" for x in c["layers"])
    p = tmp / "importlinter.ini"
    p.write_text(text)
    return p


def _copy(tmp: Path, name: str) -> Path:
    """The package's sources under another top-level name (so that the
    installed sc_rt cannot be picked up instead)."""
    dst = tmp / name
    shutil.copytree(PKG, dst, ignore=shutil.ignore_patterns("*.so", "__pycache__", "library"))
    for f in dst.rglob("*.py"):
        f.write_text(re.sub(r"\bsc_rt\b(?!_lcm)", name, f.read_text()))
    return dst


def test_layers_contract_holds_on_the_tree(tmp_path):
    dst = _copy(tmp_path, "scrt_layers_ok")
    r = _lint(_contract_config(tmp_path, dst.name), tmp_path, tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr
    n = len(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"])
    assert n >= 2 and f"{n} kept, 0 broken" in r.stdout


def _broken_by(tmp_path: Path, name: str, module: str, target: str) -> None:
    """A copy of the package in which ``module`` (a path under it) imports
    ``target`` inside a function must break the contract, naming the import."""
    dst = _copy(tmp_path, name)
    f = dst / module
    f.write_text(f.read_text() + f"\n\ndef _oops():\n    import {dst.name}.{target}  # noqa\n")
    r = _lint(_contract_config(tmp_path, dst.name), tmp_path, tmp_path)
    assert r.returncode != 0
    src = f"{dst.name}." + module.removesuffix(".py").replace("/", ".")
    flat = " ".join(r.stdout.split())  # import-linter wraps long lines
    assert "BROKEN" in r.stdout and f"{src} -> {dst.name}.{target}" in flat, r.stdout


def test_layers_contract_catches_a_lower_layer_importing_a_higher_one(tmp_path):
    _broken_by(tmp_path, "scrt_layers_bad", "model/plant.py", "cli.main")


def test_layers_contract_keeps_peer_packages_independent(tmp_path):
    _broken_by(tmp_path, "scrt_layers_peer", "emulator/twin.py", "logs.lcmlog")


def test_results_contract_keeps_the_record_below_judging_and_presenting(tmp_path):
    """results/: the record never reads the judging, the judging never the presenting."""
    _broken_by(tmp_path, "scrt_results_rec", "results/record/run.py", "results.judge.metrics")
    _broken_by(tmp_path, "scrt_results_judge", "results/judge/verdict.py", "results.present.figures")
