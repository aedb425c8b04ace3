"""Decode throughput of ``sc-rt report`` on a 1-million-event log.

The log is generated: 250 000 control steps of a 100 Hz run (plant_state_t,
plant_truth_t, wheel_cmd_t, controller_status_t each, plus the config and a
few foreign events), values random but the sequence numbers and times those
of a real run. Figures: read + decode (lcm.EventLog and the vectorised
decode, the figure ``sc-rt report`` prints), the trajectory rebuild, and the
whole report without figures; as the baseline, the generated Python decode of
every event.

    .venv/bin/python bench/bench_report.py [--quick | --smoke]

(--quick: 25 000 steps; --smoke: 2 000 steps, a check that it runs.)
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import lcm
import numpy as np
import sc_rt_lcm

from common import ROOT, machine, mode, write

from sc_rt.logs.report import read_log, rebuild, write_report  # noqa: E402
from sc_rt.scenario.reader import load_scenario  # noqa: E402
from sc_rt.wire.codec import numpy_dtype  # noqa: E402

CHANNELS = (("SCRT_STATE", sc_rt_lcm.plant_state_t), ("SCRT_CMD", sc_rt_lcm.wheel_cmd_t),
            ("SCRT_CTRL_STATUS", sc_rt_lcm.controller_status_t), ("SCRT_TRUTH", sc_rt_lcm.plant_truth_t))


def _records(cls, n: int, rng: np.random.Generator) -> np.ndarray:
    dt = numpy_dtype(cls)
    rec = np.zeros(n, dt)
    for name in dt.names:
        if dt[name].base.kind == "f":
            rec[name] = rng.normal(size=rec[name].shape) * 1e-2
    rec["_fp"] = int.from_bytes(cls._get_packed_fingerprint(), "big")
    seq = np.arange(n)
    for f in ("seq", "state_seq", "cmd_seq", "cmd_seq_applied", "steps"):
        if f in dt.names:
            rec[f] = seq
    if "t" in dt.names:
        rec["t"] = seq / 100.0
    if cls is sc_rt_lcm.plant_truth_t:  # healthy wheels, commands fresh
        rec["fault_effectiveness"], rec["fault_bias"], rec["fault_Y"] = 1.0, 0.0, 0.0
    return rec


def make_log(path: Path, steps: int, seed: int = 1) -> int:
    """A log of 4 * steps + a few events; returns the number of events."""
    rng = np.random.default_rng(seed)
    blobs = []
    for ch, cls in CHANNELS:
        rec = _records(cls, steps, rng)
        raw = rec.tobytes()
        size = rec.dtype.itemsize
        blobs.append((ch, [raw[i * size:(i + 1) * size] for i in range(steps)]))
    log = lcm.EventLog(str(path), "w", overwrite=True)
    cfg = load_scenario(ROOT / "scenarios" / "paper_fault_free.toml").controller_config_msg(
        control_rate_hz=100.0).encode()
    log.write_event(0, "SCRT_HIL_START", b"bench")
    log.write_event(1, "SCRT_CONFIG", cfg)
    n = 2
    for k in range(steps):
        ts = 1_000_000 + k * 10_000
        for j, (ch, datas) in enumerate(blobs):
            log.write_event(ts + j * 100, ch, datas[k])
        n += 4
    log.close()
    return n


def generated_decode(path: Path) -> float:
    """Baseline: every event through the generated Python decode."""
    types = dict((ch, cls) for ch, cls in CHANNELS)
    t0 = time.perf_counter()
    for e in lcm.EventLog(str(path), "r"):
        cls = types.get(e.channel)
        if cls is not None:
            cls.decode(e.data)
    return time.perf_counter() - t0


STEPS = {"full": 250_000, "quick": 25_000, "smoke": 2_000}


def main() -> None:
    size = mode()
    steps = STEPS[size]
    res = {"machine": machine()}
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.lcmlog"
        t0 = time.perf_counter()
        n = make_log(path, steps)
        res["events"] = n
        res["log_mb"] = path.stat().st_size / 1e6
        res["generate_s"] = time.perf_counter() - t0
        reads = []
        for _ in range(3):
            d = read_log(path)
            reads.append(d.decode_s)
        assert d.events == n and d.undecodable == 0, (d.events, d.undecodable)
        # the run rebuilt from the log: one row per plant state, the run's
        # fields in Rebuilt.arrays (sc_rt.results.record.run.FIELDS)
        t0 = time.perf_counter()
        r = rebuild(d)
        res["rebuild_s"] = time.perf_counter() - t0
        assert len(r.arrays["t"]) == steps and bool(r.has_truth.all()), (len(r.arrays["t"]), steps)
        t0 = time.perf_counter()
        rep = write_report(path, Path(tmp) / "report", plots=False)
        res["report_no_figures_s"] = time.perf_counter() - t0
        assert rep["rows"] == steps and rep["events"] == n and rep["undecodable"] == 0, (
            rep["rows"], rep["events"], rep["undecodable"])
        res["report_rows"] = rep["rows"]
        res["read_decode_s"] = float(np.median(reads))
        res["decode_events_per_s"] = n / res["read_decode_s"]
        base = generated_decode(path)
        res["generated_decode_s"] = base
        res["generated_decode_events_per_s"] = n / base
        res["speedup_over_generated_decode"] = base / res["read_decode_s"]
    res["target_1e6_events_in_seconds"] = (("pass" if res["report_no_figures_s"] < 10 else "miss")
                                           if size == "full" else f"not measured ({size}: {n} events)")
    write("report", res)


if __name__ == "__main__":
    main()
