"""A buildable law project (docs/LAWS.md section 3), what ``sc-rt new-law
NAME [--lang cpp|python]`` writes (cli/newlaw.py parses the command): a C++
plugin built with CMake or a Python law class, with a PD law filled in, a
pytest test that runs it in ``sc-rt sim`` and a README (:func:`scaffold`)."""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["scaffold"]


def scaffold(name: str, out: Path, lang: str = "cpp") -> list[Path]:
    """Write the project; returns the files written."""
    ident = re.sub(r"[^A-Za-z0-9_]", "_", name)
    cls = "".join(p.capitalize() for p in re.split(r"[-_]", name) if p) or "Law"
    out.mkdir(parents=True, exist_ok=True)
    subst = {"@NAME@": name, "@IDENT@": ident, "@CLASS@": cls}
    templates = _CPP if lang == "cpp" else _PYTHON
    written = []
    for fname, text in templates.items():
        for k, v in subst.items():
            fname, text = fname.replace(k, v), text.replace(k, v)
        p = out / fname
        p.write_text(text, encoding="utf-8")
        written.append(p)
    return written


#: The scaffold test's two tests, the same for both languages (each template
#: defines run(tmp_path) before them): one for any law, one for the PD.
_SCAFFOLD_TESTS = """

def test_any_law_runs_to_the_end_finite_and_never_safe(tmp_path):
    m = run(tmp_path)
    assert m["finite"] and not m.get("partial") and m["steps"] == 601  # 60 s at 10 Hz, to the end
    assert m["safe_steps"] == 0 and m["law_invalid_steps"] == 0 and m.get("valid", True)


def test_this_pd_brings_the_error_down(tmp_path):
    # law-specific (edit for your law): |sigma_BD| at the end below its value at 30 s
    norms = list(run(tmp_path)["sigma_e_norm"].values())
    assert norms[-1] < norms[0]
"""

_CPP = {
    "CMakeLists.txt": """\
# The control law @NAME@ as an sc-rt law plugin (docs/LAWS.md in sc-rt).
#   cmake -S . -B build -DCMAKE_PREFIX_PATH="$(sc-rt --cmake-dir)"
#   cmake --build build
cmake_minimum_required(VERSION 3.24)
project(@IDENT@ LANGUAGES CXX)
find_package(sc_rt CONFIG REQUIRED)
sc_rt_add_law(@IDENT@ @IDENT@.cpp)
""",
    "@IDENT@.cpp": """\
// The control law @NAME@: an sc-rt law plugin (docs/LAWS.md). It starts as a
// PD on the tracking errors the core computes,
//   u_cmd = -B+ (kp sigma_BD + kd omega_BD_B)        [rad/s^2 per wheel]
// with kp [1/s^2] and kd [1/s] from its own table in the scenario,
// [laws.@NAME@] (the name it registers below).
// Change step() to your law; keep reset() and step() free of allocation.
#include <sc_rt/law.hpp>

namespace {

class @CLASS@ final : public sc_rt::ControlLaw {
 public:
  explicit @CLASS@(const sc_rt::LawSetup& s)
      : model_(s.model), kp_(s.params.positive("kp", 0.05693)), kd_(s.params.positive("kd", 0.2386)) {}

  // Engage: set every state of the law (this PD has none).
  void reset(const sc_rt::LawInput&) override {}

  void step(const sc_rt::LawInput& in, sc_rt::LawOutput& out) override {
    out.u_cmd = -model_.B_pinv * (kp_ * in.e.sigma_BD + kd_ * in.e.omega_BD_B);
    out.e1 = in.e.sigma_BD;    // recorded as the run's e1, e2
    out.e2 = in.e.omega_BD_B;
  }

 private:
  sc_rt::LawModel model_;
  double kp_, kd_;
};

}  // namespace

SC_RT_LAW_PLUGIN("@NAME@", @CLASS@, "@NAME@: PD on sigma_BD and omega_BD_B (sc-rt new-law)")
// What u_cmd is: wheel accelerations [rad/s^2] (the default, so this line may
// go). A law of motor torques [N m] says sc_rt::LawCommand::Torque; on wheels
// that take the other, sc-rt converts exactly (torque = Jw a; docs/LAWS.md).
SC_RT_LAW_COMMAND(sc_rt::LawCommand::Acceleration)
""",
    "test_@IDENT@.py": """\
\"\"\"Builds the plugin and runs it in `sc-rt sim`: pytest test_@IDENT@.py

Works with sc-rt's interpreter whether or not its venv is activated (the
commands are found next to sys.executable). The first test holds for any
law; the second is this PD's and is the one to edit for yours.\"\"\"

import json
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
LIB = HERE / "build" / "lib@IDENT@.so"
BIN = Path(sys.executable).parent


def _tool(name):
    return str(BIN / name) if (BIN / name).exists() else (shutil.which(name) or name)


def build():
    from sc_rt.cmake import cmake_dir

    subprocess.run([_tool("cmake"), "-S", str(HERE), "-B", str(HERE / "build"), f"-DCMAKE_PREFIX_PATH={cmake_dir()}"],
                   check=True, capture_output=True)
    subprocess.run([_tool("cmake"), "--build", str(HERE / "build")], check=True, capture_output=True)


def run(tmp_path, duration=60.0):
    build()
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_fault_free", "--law", f"plugin:{LIB}",
                        "--duration", str(duration), "--no-plots", "--out", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return json.loads((out / "metrics.json").read_text())
""" + _SCAFFOLD_TESTS,
    "README.md": """\
# @NAME@: an sc-rt control law (C++ plugin)

Written by `sc-rt new-law @NAME@`. The law is in `@IDENT@.cpp` (a PD to
start from); the interface is `sc_rt/law.hpp`, documented in sc-rt's
docs/LAWS.md.

Build (one command, against the installed sc-rt):

```sh
cmake -S . -B build -DCMAKE_PREFIX_PATH="$(sc-rt --cmake-dir)" && cmake --build build
```

Run it:

```sh
sc-rt sim paper_faults --law plugin:build/lib@IDENT@.so --out out/@IDENT@
sc-rt compare paper_faults --law dsc-ppc --law pd --law plugin:build/lib@IDENT@.so
sc-rt hil paper_faults --law plugin:build/lib@IDENT@.so --mode lockstep --out out/@IDENT@-hil
```

or from a scenario file:

```toml
[controller]
law = "plugin:build/lib@IDENT@.so"   # relative to the scenario file

[laws.@NAME@]   # its parameters (a scenario holds one such table per law it may run)
kp = 0.05693   # [1/s^2]
kd = 0.2386    # [1/s]
```

Test: `pytest test_@IDENT@.py` (builds, then runs `sc-rt sim`).
""",
}

_PYTHON = {
    "@IDENT@.py": """\
\"\"\"The control law @NAME@ as a Python law (sc-rt docs/LAWS.md, "Python laws"):
the same inputs and outputs as the C++ interface, numpy arrays. It starts as a
PD on the tracking errors the core computes:
    u_cmd = -B+ (kp sigma_BD + kd omega_BD_B)        [rad/s^2 per wheel]
\"\"\"

import numpy as np


class @CLASS@:
    name = "@NAME@"
    # what u_cmd is: wheel accelerations [rad/s^2] (the default) or "torque",
    # motor torques [N m]; on wheels that take the other, sc-rt converts exactly
    command = "acceleration"

    def __init__(self, setup):
        self.B_pinv = np.asarray(setup.model.B_pinv)
        self.kp = float(setup.params.get("kp", 0.05693))  # [1/s^2]
        self.kd = float(setup.params.get("kd", 0.2386))  # [1/s]

    def reset(self, inp):
        pass  # engage: set every state of the law (this PD has none)

    def step(self, inp):
        x1, x2 = np.asarray(inp.e.sigma_BD), np.asarray(inp.e.omega_BD_B)
        u_cmd = -self.B_pinv @ (self.kp * x1 + self.kd * x2)
        return u_cmd, {"e1": x1, "e2": x2}
""",
    "test_@IDENT@.py": """\
\"\"\"Runs the law in `sc-rt sim`: pytest test_@IDENT@.py

Works with sc-rt's interpreter whether or not its venv is activated. The
first test holds for any law; the second is this PD's and is the one to
edit for yours.\"\"\"

import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def run(tmp_path, duration=60.0):
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "sc_rt.cli", "sim", "paper_fault_free", "--law",
                        f"{HERE / '@IDENT@.py'}:@CLASS@", "--duration", str(duration), "--no-plots", "--out", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    return json.loads((out / "metrics.json").read_text())
""" + _SCAFFOLD_TESTS,
    "README.md": """\
# @NAME@: an sc-rt control law (Python)

Written by `sc-rt new-law @NAME@ --lang python`. The law is the class
`@CLASS@` in `@IDENT@.py` (a PD to start from); the contract is in sc-rt's
docs/LAWS.md ("Python laws").

```sh
sc-rt sim paper_faults --law @IDENT@.py:@CLASS@ --out out/@IDENT@
pytest test_@IDENT@.py
```
""",
}
