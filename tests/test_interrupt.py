"""Interrupted and broken runs, with real processes: SIGINT/SIGTERM to
``sc-rt hil``, ``sim`` and ``montecarlo`` (children stopped, a summary, the
rows done written and marked partial, exit 130/143), the logger dying under
``sc-rt hil`` (noticed, exit 1, partial), a full disk under the output
directory (one clear line, exit non-zero), and ``sc-rt report`` on a log cut
in the middle of a step (the complete rows only). Every signal is sent once
the run shows progress (polled), never after a sleep alone."""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
from pathlib import Path

import lcm
import numpy as np
import pytest

import lcmnet
from trajcmp import load_traj

ROOT = Path(__file__).resolve().parent.parent
PY = shlex.quote(sys.executable)
CLI = f"{PY} -m sc_rt.cli"

# the command ($P) exited before the progress awaited: say so, stop the script
EARLY = 'kill -0 $P 2> /dev/null || {{ wait $P; echo "exited early: rc=$?" >&2; exit 9; }}'
# wait (up to 120 s) until FILE exists with at least N bytes
GROW = """i=0; while [ "$(stat -c %s {f} 2>/dev/null || echo 0)" -lt {n} ]; do """ + EARLY + """
  i=$((i+1)); [ $i -gt 1200 ] && echo "no progress in {f}" >&2 && exit 9; sleep 0.1; done"""
# wait (up to 120 s) until FILE holds TEXT
SAYS = """i=0; until grep -q "{t}" {f} 2>/dev/null; do """ + EARLY + """
  i=$((i+1)); [ $i -gt 1200 ] && echo "no '{t}' in {f}" >&2 && exit 9; sleep 0.1; done"""


def leftovers(token: str) -> str:
    """Processes whose command line holds ``token`` (the run's unique output directory)."""
    r = subprocess.run(["pgrep", "-af", token], capture_output=True, text=True)
    return "\n".join(line for line in r.stdout.splitlines() if "pgrep" not in line)


def metrics(out: Path) -> dict:
    return json.loads((out / "metrics.json").read_text())


def url(port: int) -> str:
    """A bench URL with large socket buffers: lockstep at full speed must not
    outrun the logger's socket (HIL.md, "Sessions")."""
    return f"udpm://239.255.76.67:{port}?ttl=0&recv_buf_size=4194304"


def assert_complete_rows(rep: Path) -> None:
    """The report's rows: every one complete (its truth and command): the
    last, and those whose plant_truth_t a busy logger lost are left out."""
    m = metrics(rep)
    with load_traj(rep) as z:
        acc, u = z["wheel_accel"], z["u_cmd"]
    assert np.all(np.isfinite(acc[-1])) and np.all(np.isfinite(u[-1]))
    assert m["max_abs_u_cmd"] is not None and np.isfinite(m["max_abs_u_cmd"])
    # rows whose truth the logger missed are left out too: every row is complete
    assert not np.isnan(acc).any() and not np.isnan(u).any()
    assert m["finite"] is True


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [("INT", 130), ("TERM", 143)])
def test_hil_interrupted(tmp_path, sig, code):
    lcmnet.require()
    out = tmp_path / f"hil-{sig}"
    log = out / "run.lcmlog"
    # 1 kHz for 300 s: minutes of lockstep, the signal lands early in it
    script = f"""
{CLI} hil paper_fault_free --control-rate 1000 --out {out} --no-plots --lcm-url '{url(7801 + code)}' \
    > {tmp_path}/o.txt 2> {tmp_path}/e.txt &
P=$!
{GROW.format(f=log, n=300_000)}
kill -{sig} $P
wait $P
echo "rc=$?"
"""
    r = lcmnet.run_script(script, timeout=300)
    err = (tmp_path / "e.txt").read_text()
    assert f"rc={code}" in r.stdout, r.stdout + r.stderr + err
    assert not leftovers(str(out)), leftovers(str(out))
    assert "STOPPED at t = " in err and f"interrupted by SIG{sig}" in err and "Traceback" not in err, err
    m = metrics(out)
    assert m["partial"] is True and m["stopped"] == f"interrupted by SIG{sig}"
    # an interrupted run is not a valid run of its scenario (issue 40), and its log's report says so too
    assert m["valid"] is False and f"interrupted by SIG{sig}" in m["invalid_reason"]
    assert 0 < m["t_reached_s"] < 300 and m["steps"] == round(m["t_reached_s"] * 1000) + 1
    assert m["finite"] is True
    assert "stale states" in (tmp_path / "o.txt").read_text()  # the summary was printed
    # the report of its log: the complete rows only, every number finite
    rep = lcmnet.run_cli(["report", str(log), "--no-plots", "--out", str(tmp_path / "rep")], netns=False)
    assert rep.returncode == 0, rep.stderr
    rm = metrics(tmp_path / "rep")
    seen = {k: rm.get(k) for k in ("valid", "invalid_reason", "partial", "stopped", "steps")}
    assert rm["valid"] is False and "stopped before its end" in rm["invalid_reason"], seen
    assert_complete_rows(tmp_path / "rep")
    # (lockstep at full speed can outrun the logger's socket: a log may miss rows, never add them)
    assert 0 < rm["steps"] <= m["steps"]


@pytest.mark.slow
def test_hil_notices_the_logger_dying(tmp_path):
    lcmnet.require()
    out = tmp_path / "hil-logger"
    log = out / "run.lcmlog"
    script = f"""
{CLI} hil paper_fault_free --control-rate 1000 --out {out} --no-plots --lcm-url '{url(7812)}' \\
    > {tmp_path}/o.txt 2> {tmp_path}/e.txt &
P=$!
{GROW.format(f=log, n=300_000)}
pkill -KILL -f '^[^ ]*sc-rt-logger .*{log}'
wait $P
echo "rc=$?"
"""
    r = lcmnet.run_script(script, timeout=300)
    err = (tmp_path / "e.txt").read_text()
    assert "rc=1" in r.stdout, r.stdout + r.stderr + err
    assert "sc-rt-logger exited" in err and "STOPPED" in err and "Traceback" not in err, err
    assert not leftovers(str(out))
    m = metrics(out)
    assert m["partial"] is True and "sc-rt-logger exited" in m["stopped"]
    assert m["valid"] is False
    assert m["t_reached_s"] < 300  # stopped, not run to its end with a log that no longer grows


@pytest.mark.slow
def test_hil_on_a_full_disk(tmp_path):
    """A tmpfs as the output directory, in a private mount namespace: one
    too small for the run's disk estimate is refused before anything starts;
    one that fills while the run writes its rows stops it with one line."""
    lcmnet.require()
    if not lcmnet.can_unshare():
        pytest.skip("needs root for a private mount namespace")
    out = tmp_path / "full"
    inner = (f"ip link set lo up && ip route add 224.0.0.0/4 dev lo && mkdir -p {out} && "
             f"mount -t tmpfs -o size=200k tmpfs {out} && "
             f"{CLI} hil paper_fault_free --control-rate 100 --out {out} --no-plots; echo rc=$?; ls -A {out}")
    r = subprocess.run(["unshare", "-m", "-n", "sh", "-c", inner], capture_output=True, text=True,
                       cwd=ROOT, timeout=300)
    assert "rc=2" in r.stdout, r.stdout + r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "on disk at most" in lines[0] and "free in" in lines[0], r.stderr
    assert r.stdout.strip().endswith("rc=2"), r.stdout  # nothing written
    assert not leftovers(str(out))
    # the estimate passes (a tmpfs 20 MB above the estimate the refusal named: rows grow as the
    # field table does), then the disk fills under the running bench
    need_mb = int(re.search(r"= (\d+) MB", lines[0]).group(1))
    grow = GROW.format(f=out / "run.lcmlog", n=3_000_000)
    inner = (f"ip link set lo up && ip route add 224.0.0.0/4 dev lo && mkdir -p {out} && "
             f"mount -t tmpfs -o size={need_mb + 20}m tmpfs {out} && "
             f"{{ {CLI} hil paper_fault_free --control-rate 100 --out {out} --no-plots & }} && P=$! && "
             f"{grow} && (dd if=/dev/zero of={out}/filler bs=1M 2>/dev/null || true) && "
             f"wait $P; echo rc=$?")
    r = subprocess.run(["unshare", "-m", "-n", "sh", "-c", inner], capture_output=True, text=True,
                       cwd=ROOT, timeout=300)
    assert "rc=0" not in r.stdout and "rc=" in r.stdout, r.stdout + r.stderr
    assert "Traceback" not in r.stderr, r.stderr
    assert "No space left on device" in r.stderr, r.stderr
    # the line names the directory (issue 40 item 5: "cannot write the outputs" before)
    assert str(out) in r.stderr, r.stderr
    assert not leftovers(str(out))


@pytest.mark.slow
@pytest.mark.parametrize("sig, code", [("INT", 130), ("TERM", 143)])
def test_sim_interrupted(tmp_path, sig, code):
    out = tmp_path / "sim"
    started = SAYS.format(f=tmp_path / "e.txt", t="rows ...")
    # the python engine at 1 kHz: 300 001 rows, seconds of work after its start line
    script = f"""
{CLI} sim paper_fault_free --control-rate 1000 --out {out} --no-plots > {tmp_path}/o.txt 2> {tmp_path}/e.txt &
P=$!
{started}
kill -{sig} $P
wait $P
echo "rc=$?"
"""
    r = lcmnet.run_script(script, timeout=300)
    err = (tmp_path / "e.txt").read_text()
    assert f"rc={code}" in r.stdout, r.stdout + r.stderr + err
    assert f"interrupted by SIG{sig}" in err and "Traceback" not in err, err
    m = metrics(out)
    assert m["partial"] is True and m["t_reached_s"] < 300 and m["steps"] < 300_001
    assert m["valid"] is False and f"interrupted by SIG{sig}" in m["invalid_reason"]


@pytest.mark.slow
def test_montecarlo_interrupted(tmp_path):
    out = tmp_path / "mc"
    script = f"""
{CLI} montecarlo paper_fault_free --runs 2000 --workers 2 --batch 2 --out {out} > {tmp_path}/o.txt 2> {tmp_path}/e.txt &
P=$!
i=0; until ls {out}/runs/*.parquet > /dev/null 2>&1; do {EARLY.replace("{{", "{").replace("}}", "}")}
  i=$((i+1)); [ $i -gt 1200 ] && echo "no batch in {out}" >&2 && exit 9; sleep 0.1; done
kill -INT $P
wait $P
echo "rc=$?"
"""
    r = lcmnet.run_script(script, timeout=300)
    err = (tmp_path / "e.txt").read_text()
    assert "rc=130" in r.stdout, r.stdout + r.stderr + err
    assert "STOPPED (interrupted by SIGINT)" in err and "Traceback" not in err, err
    s = json.loads((out / "montecarlo.json").read_text())
    assert s["partial"] is True and 0 < s["runs_done"] < 2000
    assert not leftovers(str(out))


def _cut_before_last_truth(src: Path, dst: Path) -> int:
    """``src`` without its last SCRT_TRUTH and everything after it: a log
    that ends with a state the plant never applied. Returns the events kept."""
    events = []
    log = lcm.EventLog(str(src), "r")
    for ev in log:
        events.append((ev.timestamp, ev.channel, ev.data))
    log.close()
    last = max(i for i, e in enumerate(events) if e[1] == "SCRT_TRUTH")
    out = lcm.EventLog(str(dst), "w", overwrite=True)
    for ts, ch, data in events[:last]:
        out.write_event(ts, ch, data)
    out.close()
    return last


@pytest.mark.slow
def test_report_on_a_log_cut_mid_step(tmp_path):
    lcmnet.require()
    out = tmp_path / "hil"
    r = lcmnet.run_cli(["hil", "paper_fault_free", "--duration", "20", "--out", str(out), "--no-plots",
                        "--lcm-url", url(7811)])
    assert r.returncode == 0, r.stderr
    cut = tmp_path / "cut.lcmlog"
    _cut_before_last_truth(out / "run.lcmlog", cut)
    reports = {}
    for name, log in (("whole", out / "run.lcmlog"), ("cut", cut)):
        rep = lcmnet.run_cli(["report", str(log), "--no-plots", "--out", str(tmp_path / name)], netns=False)
        assert rep.returncode == 0, rep.stderr
        reports[name] = rep.stdout
    assert "PARTIAL" in reports["cut"] and "incomplete rows at its end left out" in reports["cut"]
    assert "PARTIAL" not in reports["whole"]
    m, whole = metrics(tmp_path / "cut"), metrics(tmp_path / "whole")
    assert m["partial"] is True and m["incomplete_rows_dropped"] >= 1 and "partial" not in whole
    assert m["valid"] is False and whole["valid"] is True
    assert m["steps"] == whole["steps"] - 1
    assert_complete_rows(tmp_path / "cut")
    assert m["finite"] is whole["finite"]

    # three truths lost mid-run (a logger that fell behind): those rows left out, not partial
    events = list(lcm.EventLog(str(out / "run.lcmlog"), "r"))
    truths = [i for i, e in enumerate(events) if e.channel == "SCRT_TRUTH"]
    lose = set(truths[len(truths) // 4: len(truths) // 4 + 3])
    holes = lcm.EventLog(str(tmp_path / "holes.lcmlog"), "w", overwrite=True)
    for i, e in enumerate(events):
        if i not in lose:
            holes.write_event(e.timestamp, e.channel, e.data)
    holes.close()
    rep = lcmnet.run_cli(["report", str(tmp_path / "holes.lcmlog"), "--no-plots", "--out", str(tmp_path / "h")],
                         netns=False)
    assert rep.returncode == 0, rep.stderr
    assert "3 rows without their plant_truth_t (lost by the logger) left out" in rep.stdout, rep.stdout
    h = metrics(tmp_path / "h")
    assert "partial" not in h and h["incomplete_rows_dropped"] == 3 and h["steps"] == whole["steps"] - 3
    assert_complete_rows(tmp_path / "h")


@pytest.mark.slow
def test_hil_killed_leaves_no_orphans(tmp_path):
    """SIGKILL cannot be handled: the children still go (parent-death signal)."""
    lcmnet.require()
    out = tmp_path / "hil-KILL"
    log = out / "run.lcmlog"
    script = f"""
{CLI} hil paper_fault_free --control-rate 1000 --out {out} --no-plots --lcm-url '{url(7813)}' \\
    > {tmp_path}/o.txt 2> {tmp_path}/e.txt &
P=$!
{GROW.format(f=log, n=300_000)}
kill -KILL $P
wait $P
echo "rc=$?"
i=0; while pgrep -f '^[^ ]*(sc-rt-controller|sc-rt-logger) .*{out}' > /dev/null; do
  i=$((i+1)); [ $i -gt 600 ] && break; sleep 0.1; done
"""
    r = lcmnet.run_script(script, timeout=300)
    assert "rc=137" in r.stdout, r.stdout + r.stderr
    assert not leftovers(str(out)), leftovers(str(out))


@pytest.mark.parametrize("sig, code", [("INT", 130), ("TERM", 143)])
def test_emulator_interrupted_before_its_first_row(tmp_path, sig, code):
    """No controller: lockstep waits for the answer to state 0 and the signal
    stops it there: a run of no row, written and marked partial."""
    out = tmp_path / "emu"
    script = f"""
{CLI} emulator paper_fault_free --lcm-url memq:// --out {out} > {tmp_path}/o.txt 2> {tmp_path}/e.txt &
P=$!
{SAYS.format(f=tmp_path / 'e.txt', t='LCM URL')}
kill -{sig} $P
wait $P
echo "rc=$?"
"""
    r = lcmnet.run_script(script, timeout=120)
    err = (tmp_path / "e.txt").read_text()
    assert f"rc={code}" in r.stdout, r.stdout + r.stderr + err
    assert "STOPPED at t = - s" in err and "Traceback" not in err, err
    m = metrics(out)
    assert m["partial"] is True and m["steps"] == 0 and m["t_reached_s"] is None
    assert json.loads((out / "emulator.json").read_text())["partial"] is True
