"""Every benchmark runs, in its smoke mode (issue #24 item 5): tiny sizes, a
few seconds each, its results checked for structure and sanity (the keys
there, the numbers finite and positive where they must be), never for speed,
so a benchmark cannot rot unseen. The list is bench/run_all.py's (BENCHES, what
``make bench`` runs, and OTHER_BENCHES); every script of bench/ that is not
one of its HELPERS must be on it, and have its check here. Also: run_all
exits non-zero, naming each benchmark that failed, and still runs the others.
"""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path

import pytest

import lcmnet

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "bench"
sys.path.insert(0, str(BENCH))

import bench_netem as netem_script  # noqa: E402
import run_all  # noqa: E402

SMOKE = "not judged (smoke run)"  # bench/common.py's write: a smoke run judges no target


# --------------------------------------------------------------------------- #
# checks of the figures


def pos(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def fin(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def check_pos(res: dict, *keys: str) -> None:
    for k in keys:
        assert k in res, f"missing {k}"
        assert pos(res[k]), (k, res[k])


def check_summary(s: dict, positive: bool = True) -> None:
    """bench/common.py's summary(): unit, n, median, p99, min, max."""
    assert set(s) >= {"unit", "n", "median", "p99", "min", "max"}, s
    assert s["n"] >= 1
    assert all(fin(s[k]) for k in ("median", "p99", "min", "max")), s
    assert s["min"] <= s["median"] <= s["max"] and s["min"] <= s["p99"] <= s["max"], s
    if positive:
        assert s["min"] > 0, s


def check_percentiles(d: dict, keys=("p50", "p99")) -> None:
    """A latency's percentiles [us]: there, finite, not negative, ordered."""
    assert all(k in d and fin(d[k]) and d[k] >= 0 for k in keys), d
    if "p50" in d and "p99" in d:
        assert d["p50"] <= d["p99"], d


def check_common(res: dict) -> None:
    assert res["mode"] == "smoke"
    if "machine" in res:
        assert set(res["machine"]) >= {"cores", "cpu", "kernel", "python"}
    for k, v in res.items():
        if k.startswith("target_") and isinstance(v, str):
            assert v == SMOKE or v.startswith("not measured"), (k, v)


def check_realtime(r: dict) -> None:
    """One real-time run's figures (bench_hil, bench_external)."""
    assert isinstance(r["steps"], int) and r["steps"] > 0, r
    assert isinstance(r["deadline_misses"], int) and 0 <= r["deadline_misses"] <= r["steps"], r
    for k in ("wake_lateness_us", "state_to_cmd_latency_us", "state_age_us"):
        check_percentiles(r[k])
    assert r["stale_states"] >= 0 and r["dropped"] >= 0, r


# --------------------------------------------------------------------------- #
# each benchmark's smoke results


def bench_core(res: dict, out: str) -> None:
    steps = [k for k in res if k.startswith("step_") and k.endswith("_ns") and not k.endswith("_batch_ns")]
    assert len(steps) == 4, steps  # the four built-in laws
    for k in steps:
        check_summary(res[k])
        check_pos(res, k.removesuffix("_ns") + "_batch_ns")
    assert "step_dsc-ppc_ns" in steps
    check_pos(res, "pybind_step_call_ns", "numpy_step_dsc-ppc_ns", "ratio_numpy_over_cpp")
    assert fin(res["pybind_overhead_ns"])
    assert "target_dsc-ppc_step_le_1us" in res


def bench_sim(res: dict, out: str) -> None:
    for key in ("10hz", "100hz", "1000hz"):
        for engine in ("cpp", "python"):
            check_summary(res[f"{engine}_{key}_loop_s"])
            check_summary(res[f"{engine}_{key}_run_s"])
            check_pos(res, f"{engine}_{key}_step_us")
        check_pos(res, f"python_{key}_run_300s_estimate_s", f"ratio_python_over_cpp_{key}")
    assert {"target_cpp_10hz_le_5ms", "target_python_10hz_le_150ms"} <= set(res)
    for key in ("10hz", "100hz"):  # the engine side by side with the bare loop (issue #31)
        side = res[f"cpp_{key}_engine_vs_bare"]
        check_summary(side["bare_loop_s"])
        check_summary(side["engine_loop_s"])
        check_pos(side, "engine_over_bare")
        assert side["target_le_1.3x"] == SMOKE


def bench_montecarlo(res: dict, out: str) -> None:
    assert res["runs_per_campaign"] >= 1
    check_pos(res, "simulate_s", "run_one_s", "seeding_s_id_0", "seeding_s_id_1e6", "seeding_ratio_1e6_over_0",
              "old_seeding_s_id_1e4", "old_seeding_s_id_1e5", "dataset_bytes_per_row_as_run",
              "dataset_bytes_per_row_batch_64", "dataset_bytes_per_row_one_file", "dataset_columns")
    for kind in ("pool", "dask"):
        for w in (1, 2):
            check_pos(res, f"runs_per_s_{kind}_{w}")
            assert all(pos(x) for x in res[f"all_runs_per_s_{kind}_{w}"])
            assert fin(res[f"overhead_s_per_run_{kind}_{w}"])
        check_pos(res, f"scaling_{kind}_2_over_1", f"efficiency_{kind}_2", f"wall_s_1e5_runs_{kind}_2")
    check_pos(res, "dask_efficiency_over_pool_2", "dask_throughput_over_pool_2")


def bench_hil(res: dict, out: str) -> None:
    check_percentiles(res["lcm_floor_rtt_us"])
    assert res["lcm_floor_rtt_us"]["p50"] > 0
    check_pos(res, "lockstep_steps_per_s", "ratio_lockstep_step_over_floor_rtt")
    assert all(pos(x) for x in res["lockstep_steps_per_s_runs"])
    check_percentiles(res["lockstep_latency_us"])
    assert res["target_lockstep_ge_5000"] == SMOKE
    for key in ("realtime_1000hz_other", "realtime_1000hz_fifo"):
        r = res[key]
        check_realtime(r)
        assert isinstance(r["scheduler"], str) and 0 <= r["miss_fraction"] <= 1, r
    assert res["target_realtime_1khz"] == SMOKE


def bench_timing(res: dict, out: str) -> None:
    assert "failed" not in res, res.get("failed")
    rows = res["rows"]
    # hil's defaults (100 Hz), 100 Hz, 1 kHz, lockstep at 10 Hz and at 1 kHz, timer, CPU placement
    assert len(rows) == 7, list(rows)
    assert "100 Hz, hil's defaults" in rows and "--trigger" not in rows["100 Hz, hil's defaults"]["args"]
    assert sum(n.startswith("lockstep") for n in rows) == 2
    k = rows["lockstep 1 kHz + sc-rt-logger"]
    assert k["scenario"] == "ppc_feasible_1khz" and "6000" in k["checks"][0]["target"], k["checks"][0]
    assert k["steps"] == 1001 and all(pos(x) for x in k["steps_per_s_runs"]), k
    for name, row in rows.items():
        assert row["runs"] >= 1 and row["checks"], name
        for c in row["checks"]:
            assert set(c) >= {"figure", "target", "measured", "unit", "pass", "miss_by"}, c
            assert c["measured"] is None or fin(c["measured"]), c
        check_percentiles(row["latency_us"])
        assert isinstance(row["breakdown_us"], dict) and row["breakdown_us"], name
        assert "profile_top" not in row  # a smoke run profiles nothing
    for name, row in rows.items():  # the spill's effect on the tick: measured on every real-time run
        if not name.startswith("lockstep"):
            for r in row["per_run"]:
                sp = r["spill"]
                # 1 s runs: fewer rows than the two chunks before the first spill
                assert sp["chunk_rows"] > 0 and sp["spills"] == 0 and sp["around_spills_us"]["p99"] is None, sp
                assert fin(sp["elsewhere_us"]["p99"]) and sp["record_writer_waits"] == 0, sp
                # a run that did not keep real time is measured, not a failed row (the machine's load decides)
                assert r["kept_real_time"] in (True, False), r
    lock = rows["lockstep + sc-rt-logger"]
    assert lock["steps"] > 0 and all(pos(x) for x in lock["steps_per_s_runs"]), lock
    assert all(pos(x) for x in lock["latency_p99_over_floor_p99"]), lock
    # the table after the JSON, every row in it
    table = out[out.rindex("\nrow "):]
    assert all(name in table for name in rows), table


def bench_external(res: dict, out: str) -> None:
    assert res["lockstep_duration_s"] > 0
    for name in ("cpp_pd", "python_law_pd", "external_example"):
        check_pos(res, f"{name}_steps_per_s")
        assert all(pos(x) for x in res[f"{name}_steps_per_s_runs"])
        assert isinstance(res[f"{name}_law"], str) and res[f"{name}_law"]
        check_percentiles(res[f"{name}_latency_us"])
    for rate in (10, 100):
        r = res[f"python_law_realtime_{rate}hz"]
        check_realtime(r)
        check_percentiles(r["compute_us"])
    assert res["target_external_ge_1000"] == SMOKE


def _log_bench(res: dict, steps: int = 2000) -> None:
    """bench_report.py's generated log: four messages per step, the config and a start marker."""
    assert res["events"] == 4 * steps + 2, res["events"]
    check_pos(res, "log_mb", "generate_s")


def bench_report(res: dict, out: str) -> None:
    _log_bench(res)
    assert res["report_rows"] == 2000
    check_pos(res, "rebuild_s", "report_no_figures_s", "read_decode_s", "decode_events_per_s",
              "generated_decode_s", "generated_decode_events_per_s", "speedup_over_generated_decode")
    assert res["target_1e6_events_in_seconds"].startswith("not measured")


def bench_mcap(res: dict, out: str) -> None:
    _log_bench(res)
    check_pos(res, "mcap_mb", "messages", "export_s", "events_per_s")
    assert res["derived"] and all(isinstance(v, int) and v > 0 for v in res["derived"].values()), res["derived"]
    assert all(pos(x) for x in res["export_s_runs"])
    assert res["target_1e6_events_in_seconds"].startswith("not measured")


def bench_sensors(res: dict, out: str) -> None:
    check_summary(res["loop_no_sensors_s"])
    for k in ("gyro_100hz", "gyro_10hz", "gyro_100hz_truth_fed"):
        check_summary(res[f"loop_{k}_s"])
        assert fin(res[f"overhead_{k}_fraction"]) and fin(res[f"nav_{k}_per_control_step_us"])
    check_summary(res["law_100hz_loop_no_sensors_s"])
    check_summary(res["law_100hz_loop_gyro_100hz_s"])
    assert res["control_steps"] > 0
    for k in ("gyro_100hz", "gyro_10hz", "law_100hz"):
        e = res["estimator"][k]
        check_pos(e, "per_step_us", "min_per_step_us", "control_steps", "gyro_samples", "sensors_per_run_s")
        check_pos(res, f"estimator_{k}_per_control_step_us")
    assert all(fin(v) for k, v in res["breakdown"].items() if k != "note"), res["breakdown"]
    assert len(res["targets"]) == 6
    for name, t in res["targets"].items():
        assert t["result"] in ("pass", "miss") and fin(t["value"]) and pos(t["target"]), (name, t)
        assert name in out  # the verdicts printed after the JSON


def bench_live(res: dict, out: str) -> None:
    ways = ("no_live", "live_no_client", "live_client")
    for way in ways:
        assert len(res["runs"][way]) == 1, res["runs"]
        m = res[way]
        assert pos(m["latency_p99_us"]) and m["latency_p50_us"] <= m["latency_p99_us"], m
        assert 0 <= m["fresh_fraction"] <= 1 and m["steps"] > 0, m
        assert way in out  # the table after the JSON
    assert res["live_client"]["client_states"] > 0 and res["live_client"]["client_messages"] > 0
    check_pos(res, "live_no_client_p99_over_no_live", "live_client_p99_over_no_live")


def bench_env(res: dict, out: str) -> None:
    for k in ("orbit_gg", "sun", "igrf_eci", "dipole_eci", "wmm2025_eci", "plant_step_orbit", "plant_step_w0"):
        check_summary(res[f"{k}_us"])
    assert res["evaluations_per_run"] == 1000
    assert fin(res["orbit_gg_added_to_plant_step_us"]) and pos(res["day_at_10hz_igrf_s"])
    assert res["target_igrf_us"] == SMOKE


def bench_day(res: dict, out: str) -> None:
    """bench_day.py: 10 min of day_hold on the C++ engine, its bare loop and the field's cost."""
    assert res["scenario"] == "day_hold" and res["duration_s"] == 600.0 and res["control_steps"] == 6000
    check_summary(res["engine_wall_s"])
    check_summary(res["bare_loop_s"])
    check_pos(res, "engine_us_per_step", "bare_us_per_step", "igrf_eval_us", "igrf_share_of_bare_step",
              "day_engine_s")
    assert res["igrf_evals_per_step"] == 5  # 4 RK4 stages of the one plant step, and the controller's
    assert res["target_day_le_10s"] == SMOKE


def bench_netem(res: dict, out: str) -> None:
    if "skipped" in res:
        pytest.skip(f"bench_netem --smoke: {res['skipped']}")
    assert res["backend"] in ("netem", "emulated")
    cases = res["cases"]
    assert [c["case"] for c in cases] == [c for c, _ in netem_script.CASES if c in netem_script.SMOKE_CASES]
    for c in cases:
        if not c["run"]:  # a delay case where neither netem nor the NFQUEUE delay line is
            assert c["why"], c
            continue
        assert c["controller_alive"], c["case"]
        assert c["rows"] > 0 and pos(c["wall_s"]), c["case"]
        assert set(c["checks"]) >= {"to_controller", "to_emulator"}, c["case"]
        for side in ("to_controller", "to_emulator"):
            assert c["checks"][side]["lost"] >= 0, (c["case"], side)
        check_percentiles(c["latency_us"])
        assert fin(c["result"]["max_sigma_BD_after_10s"]), c["case"]
    assert sum(c["run"] for c in cases) >= 2, "at least the clean link and the corruption case (nftables)"
    assert len(res["design"]) == 1
    for d in res["design"]:
        assert pos(d["latency_s"]) and fin(d["min_phase_margin_deg"]) and fin(d["min_delay_margin_s"]), d
    assert "bench_netem: " in out and "sc-rt design --latency" in out


def soak(res: dict, out: str) -> None:
    assert res["rows"] == 601 and res["controller_steps"] > 0.9 * res["rows"], res["rows"]
    assert set(res["memory"]) == {"emulator", "controller"}, res["memory"]
    for m in res["memory"].values():
        assert m["rss_start_kb"] > 0 and m["span_s"] > 0 and isinstance(m["flat"], bool), m
    assert res["lost_log_events"] == 0, res["log"]
    assert set(res["log"]) == {"SCRT_STATE", "SCRT_GUIDANCE", "SCRT_TRUTH", "SCRT_CMD", "SCRT_CTRL_STATUS"}
    assert set(res["timing"]) >= {"latency_us"}, res["timing"]
    assert "soak: ok" in out


def bench_format(res: dict, out: str) -> None:
    """bench_format.py: each format's figures for the short (10 s at 10 Hz) and the long (2 s at 1 kHz) run."""
    assert res["chunk_rows"] > 0 and pos(res["long_simulate_s"])
    for which, rows in (("short", 101), ("long", 2001)):
        r = res[which]
        assert r["rows"] == rows and r["batches"] >= 1 and r["fields"] > 0, r
        sizes = {}
        for fmt in ("arrow_lz4", "arrow_zstd", "parquet", "npz"):
            f = r[fmt]
            check_pos(f, "bytes", "bytes_per_row", "write_s", "read_all_s", "read_one_column_s", "numpy_bytes")
            assert f["append_batch_ms_median"] is None if fmt == "npz" else pos(f["append_batch_ms_median"]), f
            sizes[fmt] = f["numpy_bytes"]
        assert len(set(sizes.values())) == 1, sizes  # every format gave back the same numpy arrays
        assert r["repeats"] == 1 and pos(r["arrow_lz4"]["sc_rt_read_all_s"]), r
    assert "arrow_lz4" in out and "long: 2001 rows" in out


def bench_day_lockstep(res: dict, out: str) -> None:
    """bench_day_lockstep.py: 60 s of day_hold in lockstep, bitwise the C++ engine's run."""
    assert res["scenario"] == "day_hold" and res["duration_s"] == 60.0 and res["rows"] == 601
    assert res["valid"] is True and res["bitwise_equal_sim"] is True and res["first_difference"] is None, res
    # the rods' commands and the field travelled and were compared, with the core trajectory
    assert {"rod_dipole_cmd", "B_B", "m_B_cmd", "wheel_fill", "h_wheels_B", "sigma_BN"} <= set(res["fields_compared"])
    check_pos(res, "lockstep_wall_s", "lockstep_steps_per_s", "sim_cpp_wall_s")
    assert set(res["requirements"]) == {"pointing", "wheel_speed", "momentum"}, res["requirements"]
    assert res["target_bitwise_equal_sim"] == SMOKE


# --------------------------------------------------------------------------- #
# the benchmarks: their check, extra arguments, where they write, marks, timeout [s]

LCM = (pytest.mark.lcm, pytest.mark.slow)
SPECS = {
    "bench_core.py": dict(check=bench_core),
    "bench_sim.py": dict(check=bench_sim, marks=(pytest.mark.slow,)),  # ~0.8 s: the side-by-side rows
    "bench_montecarlo.py": dict(check=bench_montecarlo, marks=(pytest.mark.slow,)),  # ~7 s: Dask clusters
    "bench_hil.py": dict(check=bench_hil, marks=LCM, timeout=180),
    "bench_timing.py": dict(check=bench_timing, marks=LCM, timeout=240),
    "bench_external.py": dict(check=bench_external, marks=LCM, timeout=180),
    "bench_report.py": dict(check=bench_report),
    "bench_mcap.py": dict(check=bench_mcap),
    "bench_sensors.py": dict(check=bench_sensors),
    "bench_live.py": dict(check=bench_live, marks=LCM, timeout=180),
    "bench_env.py": dict(check=bench_env, marks=(pytest.mark.slow,)),  # ~1.2 s: the module import and its runs
    "bench_format.py": dict(check=bench_format, marks=(pytest.mark.slow,)),  # ~3 s: two runs, four formats
    "bench_day.py": dict(check=bench_day, marks=(pytest.mark.slow,)),  # ~2 s: the module import and two runs
    # root: network namespaces and nftables / tc netem (skips, saying why, elsewhere)
    "bench_netem.py": dict(check=bench_netem, marks=LCM, timeout=240, out=["--out", "{dir}/netem.json"]),
    "bench_day_lockstep.py": dict(check=bench_day_lockstep, marks=LCM, timeout=180),
    "soak.py": dict(check=soak, marks=LCM, timeout=120,
                    out=["--out", "{dir}/soak_run", "--json", "{dir}/soak.json"]),
}
ALL = [*run_all.BENCHES, *run_all.OTHER_BENCHES]


def test_every_bench_script_is_listed_and_checked():
    scripts = {p.name for p in BENCH.glob("*.py")}
    listed = set(ALL)
    assert len(ALL) == len(listed), "a benchmark listed twice in bench/run_all.py"
    assert not (listed & run_all.HELPERS)
    # a new script in bench/ is a benchmark run_all lists, or a helper it names
    assert scripts - run_all.HELPERS == listed, (
        f"not in bench/run_all.py's BENCHES, OTHER_BENCHES or HELPERS: {sorted(scripts - run_all.HELPERS - listed)}; "
        f"listed but missing: {sorted(listed - scripts)}")
    assert set(SPECS) == listed, f"benchmarks without a smoke check here: {sorted(listed - set(SPECS))}"


@pytest.mark.parametrize("script", [pytest.param(s, marks=SPECS.get(s, {}).get("marks", ())) for s in ALL])
def test_bench_smoke(script, tmp_path, request):
    spec = SPECS.get(script)
    assert spec is not None, f"{script}: add its smoke check to SPECS"
    if request.node.get_closest_marker("lcm"):
        lcmnet.require()
    env = dict(os.environ, **{"SC_RT_BENCH_RESULTS": str(tmp_path)})
    extra = [a.format(dir=tmp_path) for a in spec.get("out", [])]
    # the benchmark makes its own network namespaces (lcmnet.wrap, unshare, ip netns) where it needs them
    r = lcmnet.run([sys.executable, str(BENCH / script), "--smoke", *extra], timeout=spec.get("timeout", 90),
                   env=env, netns=False)
    assert r.returncode == 0, f"{script} --smoke exited {r.returncode}:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    path = tmp_path / f"{run_all.result_name(script)}.json"
    assert path.is_file(), f"{script} --smoke wrote no {path.name}:\n{r.stdout[-2000:]}"
    res = json.loads(path.read_text())
    if "skipped" not in res:
        check_common(res)
        printed = _last_printed_json(r.stdout)
        if script not in ("bench_netem.py", "soak.py"):  # those print a summary, not their JSON
            assert printed == res, "the printed JSON is not the written one"
    spec["check"](res, r.stdout)


def _last_printed_json(out: str):
    """The last JSON object printed at the start of a line ("{" alone on it: json.dumps(indent=2))."""
    dec = json.JSONDecoder()
    found = None
    i = 0
    while (j := out.find("{\n", i)) >= 0:
        if j == 0 or out[j - 1] == "\n":
            try:
                found, end = dec.raw_decode(out, j)
                i = end
                continue
            except ValueError:
                pass
        i = j + 1
    return found


# --------------------------------------------------------------------------- #
# run_all fails, naming each benchmark that failed, and runs the others

OK = """import json, os, sys
from pathlib import Path
d = Path(os.environ["SC_RT_BENCH_RESULTS"])
d.mkdir(parents=True, exist_ok=True)
(d / "{name}.json").write_text(json.dumps({{"argv": sys.argv[1:], "value": 1.5, "target_x": "pass"}}))
"""


def test_run_all_exits_nonzero_naming_each_failed_bench(tmp_path):
    benches = tmp_path / "benches"
    benches.mkdir()
    (benches / "bench_ok.py").write_text(OK.format(name="ok"))
    (benches / "bench_crash.py").write_text("raise SystemExit(3)\n")
    (benches / "bench_silent.py").write_text("print('measured nothing')\n")  # exit 0, no results
    (benches / "bench_after.py").write_text(OK.format(name="after"))
    out = tmp_path / "results"
    env = dict(os.environ, SC_RT_BENCH_RESULTS=str(out))
    args = [str(benches / b) for b in ("bench_ok.py", "bench_crash.py", "bench_silent.py")]
    args += ["bench_does_not_exist.py", str(benches / "bench_after.py")]
    r = lcmnet.run([sys.executable, str(BENCH / "run_all.py"), "--smoke", *args], timeout=60, env=env, netns=False)
    assert r.returncode == 1, (r.returncode, r.stderr)
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("run_all: 3 of 5 benchmarks failed"), r.stderr
    for name, why in (("bench_crash.py", "exit code 3"), ("bench_silent.py", "wrote no"),
                      ("bench_does_not_exist.py", "not found")):
        assert name in last and why in last, (name, last)
    assert "bench_ok.py" not in last and "bench_after.py" not in last
    # the others ran (the one after the failures too), with the flag, and are in results.json/.md
    res = json.loads((out / "results.json").read_text())
    assert set(res) == {"ok", "after"}
    assert res["ok"]["argv"] == ["--smoke"] == res["after"]["argv"]
    assert "| ok | value | 1.5 | |" in (out / "results.md").read_text()


def test_run_all_refuses_an_unknown_option(tmp_path):
    env = dict(os.environ, SC_RT_BENCH_RESULTS=str(tmp_path))
    r = lcmnet.run([sys.executable, str(BENCH / "run_all.py"), "--fast"], timeout=60, env=env, netns=False)
    assert r.returncode == 2 and "unknown option --fast" in r.stderr
    assert not (tmp_path / "results.json").exists()


# --------------------------------------------------------------------------- #
# a real-time run that did not keep real time is a measurement, not a crash

def test_a_benchmarks_missed_real_time_run_is_measured_and_other_failures_raise(tmp_path):
    """The fresh-clone make test's bench_hil --smoke crashed on a loaded
    machine: its 1 kHz real-time run kept 867 steps/s, sc-rt hil exited 1 and
    the benchmark raised instead of reporting the miss (common.hil_timing)."""
    import common

    (tmp_path / "timing.json").write_text(json.dumps({"kept_real_time": False, "steps": 867}))
    assert common.hil_timing(1, tmp_path, "1 kHz")["kept_real_time"] is False
    for rc in (2, 139):  # a bad option, a crash: not a measurement
        with pytest.raises(RuntimeError, match=f"1 kHz: sc-rt hil exited {rc}"):
            common.hil_timing(rc, tmp_path, "1 kHz", "boom")
    (tmp_path / "timing.json").write_text(json.dumps({"kept_real_time": True, "steps": 1000}))
    with pytest.raises(RuntimeError):  # exit 1 of a run that kept real time: another failure
        common.hil_timing(1, tmp_path, "1 kHz")
    (tmp_path / "timing.json").unlink()
    with pytest.raises(RuntimeError):  # no record at all
        common.hil_timing(1, tmp_path, "1 kHz")
