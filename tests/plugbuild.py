"""Law plugins built out of tree against the installed package, as a user's
project is (find_package(sc_rt) from `python -m sc_rt.cmake`): the example
law and the broken or special laws of tests/law_plugins."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import sc_rt.cmake

ROOT = Path(__file__).resolve().parent.parent
BIN = Path(sys.executable).parent


def cmake() -> str:
    exe = BIN / "cmake"
    return str(exe) if exe.exists() else (shutil.which("cmake") or "cmake")


def build(src: Path, build_dir: Path) -> None:
    """Configure and build the CMake project at `src` in `build_dir`."""
    cfg = [cmake(), "-S", str(src), "-B", str(build_dir), f"-DCMAKE_PREFIX_PATH={sc_rt.cmake.cmake_dir()}"]
    for cmd in (cfg, [cmake(), "--build", str(build_dir), "-j2"]):
        r = subprocess.run(cmd, capture_output=True, text=True)
        assert r.returncode == 0, r.stdout + r.stderr


def build_all(d: Path) -> dict[str, Path]:
    """examples/quaternion_feedback (key "qf") and every tests/law_plugins
    library (key: its name without the t_ prefix)."""
    build(ROOT / "examples" / "quaternion_feedback", d / "qf")
    build(ROOT / "tests" / "law_plugins", d / "bad")
    libs = {"qf": d / "qf" / "libquaternion_feedback.so"}
    for p in (d / "bad").glob("libt_*.so"):
        libs[p.stem.removeprefix("libt_")] = p
    return libs
