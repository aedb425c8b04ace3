"""A ``[laws.NAME]`` table that matches no law (issue 41, item 5): a
misspelling (``[laws.smc-mpr]`` for ``smc-mrp``) used to pass ``sc-rt
check`` with 0 errors while the law ran its compiled defaults. A table is
named by its law: a built-in, the file's law, or a law the command names
with ``--law`` (a plugin's declared name, a Python law's ``name``, else its
class name). A table near one of those names is an error, exit 2, naming the
file, the table's line and the nearest law; a table near none is another
law's (one file serves ``compare`` across laws): a note, the run goes on.

And ``sc-rt check --law file.py:Class`` is taken, as sim, hil, compare and
montecarlo take it (it was refused: "invalid choice").
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sc_rt.cli import main
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
LIB = ROOT / "python" / "sc_rt" / "scenario" / "library"
PY_PD = f"{ROOT}/examples/python_laws/pd.py:PythonPD"  # name = "python-pd"


def with_table(tmp_path: Path, header: str, law: str | None = None, name: str = "s.toml") -> Path:
    """The shipped PD hold with its [laws.pd] table renamed ``header``
    (and its law ``law``)."""
    text = (LIB / "mrp_feedback_requirements.toml").read_text()
    assert "\n[laws.pd]\n" in text
    text = text.replace("\n[laws.pd]\n", f"\n{header}\n")
    if law:
        text = text.replace('controller = "pd"', f'controller = "{law}"')
    p = tmp_path / name
    p.write_text(text)
    return p


def line_of(p: Path, text: str) -> int:
    return next(i for i, line in enumerate(p.read_text().splitlines(), 1) if line.startswith(text))


def error_line(err: str) -> str:
    lines = [x for x in err.splitlines() if x.strip()]
    assert len(lines) == 1, err  # one line
    return lines[0]


@pytest.mark.parametrize("header, law, nearest", [
    ("[laws.pdd]", None, "pd"),                     # the file's own law, misspelt
    ("[laws.dsc-pcc]", None, "dsc-ppc"),            # a built-in the file does not run
    ("[laws.python-pdd]", PY_PD, "python-pd"),      # a Python law named by --law
    ('[laws."Python-PD"]', PY_PD, "python-pd"),     # its name in another case
], ids=["own", "builtin", "python", "case"])
def test_a_misspelt_table_exits_2_naming_file_line_and_nearest_law(tmp_path, capsys, header, law, nearest):
    p = with_table(tmp_path, header)
    args = ["--law", law] if law else []
    assert main(["sim", str(p), *args, "--out", str(tmp_path / "o"), "--no-plots", "--duration", "5"]) == 2
    line = error_line(capsys.readouterr().err)
    table = header.strip("[]").replace('"', "")
    assert line.startswith(f"sc-rt: {p}:{line_of(p, header)}: {table}: matches no law"), line
    assert f'the nearest law name is "{nearest}"' in line, line
    assert not (tmp_path / "o" / "metrics.json").exists()  # nothing ran
    # sc-rt check: an error, exit 2, with the file and line
    rc = main(["check", str(p), "--fast", *args])
    out = capsys.readouterr().out
    assert rc == 2, out
    assert f"ERROR   {table}: matches no law" in out and f"({p}:{line_of(p, header)})" in out, out


def test_a_python_law_without_a_name_is_named_by_its_class(tmp_path, capsys):
    """A lower-case table for a class without ``name`` was silently ignored."""
    src = (ROOT / "examples" / "python_laws" / "pd.py").read_text()
    law = tmp_path / "nameless.py"
    law.write_text(src.replace('    name = "python-pd"\n', "", 1))
    assert 'name = "python-pd"' not in law.read_text().split("class QuaternionFeedback")[0]
    p = with_table(tmp_path, "[laws.pythonpd]")
    spec = f"{law}:PythonPD"
    assert main(["sim", str(p), "--law", spec, "--out", str(tmp_path / "o"), "--no-plots", "--duration", "5"]) == 2
    assert 'the nearest law name is "PythonPD"' in error_line(capsys.readouterr().err)
    p = with_table(tmp_path, "[laws.PythonPD]", name="right.toml")
    assert main(["sim", str(p), "--law", spec, "--out", str(tmp_path / "o"), "--no-plots", "--duration", "5"]) == 0


def test_each_laws_own_table_runs_and_another_laws_is_a_note(tmp_path, capsys):
    """The file's law is pd, its table [laws.python-pd]: run as pd it is another
    law's table (a note, the run goes on with pd's defaults); run with
    --law PythonPD it is that law's table, which the law reads (its first
    command is -B+ (beta1 sigma + beta2 omega) with the file's gains, computed here)."""
    import refmath
    from sc_rt.scenario.reader import load_scenario

    p = with_table(tmp_path, "[laws.python-pd]")
    assert main(["sim", str(p), "--out", str(tmp_path / "pd"), "--no-plots", "--duration", "5"]) == 0
    err = capsys.readouterr().err
    assert f"sc-rt: note: {p}:{line_of(p, '[laws.python-pd]')}: [laws.python-pd] is read by no law of this " \
           "run (pd)" in err, err
    assert main(["sim", str(p), "--law", PY_PD, "--out", str(tmp_path / "py"), "--no-plots", "--duration", "5"]) == 0
    assert "note" not in capsys.readouterr().err
    scn = load_scenario(p)
    table = dict(scn.controller.laws)["python-pd"]
    beta1, beta2 = table[0][1][0], table[1][1][0]
    assert (table[0][0], table[1][0]) == ("beta1", "beta2")
    x1 = refmath.mrp_sub(np.asarray(scn.initial.sigma_BN), np.asarray(scn.guidance.sigma_d0))
    x2 = np.asarray(scn.initial.omega_BN_B)  # an inertial hold: no reference rate
    pl = scn.plant
    B = -np.linalg.inv(pl.J0) @ pl.Cbar @ np.diag(pl.Jw)
    u0 = load_traj(tmp_path / "py")["u_cmd"][0]
    np.testing.assert_allclose(u0, -np.linalg.pinv(B) @ (beta1 * x1 + beta2 * x2), rtol=1e-9)
    # compare names both laws: no note, both run
    assert main(["compare", str(p), "--law", "pd", "--law", PY_PD, "--duration", "5",
                 "--out", str(tmp_path / "c")]) == 0
    assert "note" not in capsys.readouterr().err
    rows = json.loads((tmp_path / "c" / "compare.json").read_text())["rows"]
    assert [r["law"] for r in rows] == ["pd", "python-pd"]


def test_check_takes_a_python_law(tmp_path, capsys):
    p = with_table(tmp_path, "[laws.python-pd]")
    rc = main(["check", str(p), "--fast", "--law", PY_PD])
    out = capsys.readouterr().out
    assert rc in (0, 1), out  # warnings are the scenario's; the law is taken
    assert f"sc-rt check: {p} for python:{PY_PD}: 0 errors" in out, out
    # a Python law that does not load: one line, exit 2, as sim says it
    with pytest.raises(SystemExit) as e:
        main(["check", str(p), "--law", f"{tmp_path}/missing.py:Law"])
    assert e.value.code == 2 and "--law" in capsys.readouterr().err
