"""A lossy, slow link between controller and plant (issue #20): real-time
runs at 100 Hz across two network namespaces joined by a veth pair, the
link impaired on both ends, each case compared with what the impairment was
configured to do (binomial bounds, bench/netem_lab.py) and with a clean
link, and the added delay with ``sc-rt design --latency``.

    python bench/bench_netem.py [--duration 30] [--out bench/results/netem.json] [--backend auto|netem|emulated]
                                [--smoke]

--smoke: a check that it runs: the clean link, a delay (with jitter) and the
authenticated corruption case, 2 s each, and the margins at one latency.

The impairment is ``tc netem`` where the kernel has it (CONFIG_NET_SCH_NETEM);
otherwise ("emulated", netem_lab.backend_for) nftables on the veth's egress
for loss, duplication and corruption of one payload byte, and the NFQUEUE
delay line (bench/nfq_delay.py) for delay, jitter and reordering, whose
record is the exact count the receivers are compared with. Needs root.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

import netem_lab  # noqa: E402
from common import results_dir  # noqa: E402

#: the cases a smoke run takes: the baseline, one per backend (the NFQUEUE delay
#: line where there is no tc netem; nftables), and the auth key
SMOKE_CASES = ("clean link", "delay 2 ms +- 1 ms", "corruption 1 %, --auth-key")

CASES = [
    ("clean link", None),
    ("loss 1 %", "loss 1%"),
    ("loss 5 %", "loss 5%"),
    ("loss 20 %", "loss 20%"),
    ("loss 50 % (SAFE engages)", "loss 50%"),
    ("delay 2 ms +- 1 ms", "delay 2ms 1ms"),
    ("delay 2 ms, reordering 25 %", "delay 2ms reorder 25% 50%"),
    ("delay 10 ms +- 8 ms (a channel reorders)", "delay 10ms 8ms"),
    ("delay 10 ms +- 4 ms normal", "delay 10ms 4ms distribution normal"),
    ("duplication 5 %", "duplicate 5%"),
    ("corruption 1 %", "corrupt 1%"),
    ("corruption 1 %, --auth-key", "corrupt 1%"),
]


def design_margins(scenario: str, latency_s: float, work: Path) -> dict:
    """The PD baseline loop's margins with the Pade delay (sc-rt design --latency)."""
    out = work / f"design_{latency_s:g}"
    subprocess.run([sys.executable, "-m", "sc_rt.cli", "design", str(ROOT / "scenarios" / f"{scenario}.toml"),
                    "--latency", f"{latency_s:g}", "--no-plots", "--out", str(out)],
                   check=True, capture_output=True, cwd=ROOT)
    d = json.loads((out / "design.json").read_text())
    pade = [m for m in d["margins"] if m["case"] == "pade" and m["inertia"] == "true"]
    return {"latency_s": latency_s, "min_phase_margin_deg": min(m["pm"] for m in pade),
            "min_delay_margin_s": min(m["delay_margin"] for m in pade)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=None, help="[s] per case (default 30; --smoke: 2)")
    ap.add_argument("--rate", type=float, default=100.0)
    ap.add_argument("--scenario", default="ppc_feasible_100hz")
    ap.add_argument("--backend", choices=("auto", "netem", "emulated"), default="auto")
    ap.add_argument("--out", default=str(results_dir() / "netem.json"))
    ap.add_argument("--smoke", action="store_true",
                    help="a check that it runs: three cases, 2 s each unless --duration, one design latency")
    args = ap.parse_args()
    if args.duration is None:
        args.duration = 2.0 if args.smoke else 30.0
    cases = [c for c in CASES if c[0] in SMOKE_CASES] if args.smoke else CASES
    backend = args.backend
    if backend == "auto":
        backend = "netem" if netem_lab.netem_available() is None else "emulated"
    why = netem_lab.netem_available() if backend == "netem" else netem_lab.nft_available()
    if why:
        print(f"bench_netem: cannot impair a link here: {why}", file=sys.stderr)
        if args.smoke:  # the smoke run says why it did nothing, and does not fail
            out = Path(args.out)
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_text(json.dumps({"mode": "smoke", "backend": backend, "skipped": why}, indent=2) + "\n")
            print(f"bench_netem: smoke run skipped: {why}")
            return 0
        return 2
    no_queue = netem_lab.nfqueue_available() if backend == "emulated" else None
    results = {"backend": backend, "netem_here": netem_lab.netem_available() or "available",
               "nfqueue_here": netem_lab.nfqueue_available() or "available",
               "duration_s": args.duration, "rate_hz": args.rate, "scenario": args.scenario,
               "mode": "smoke" if args.smoke else "full", "cases": []}
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        key = work / "lab.key"
        key.write_bytes(b"bench_netem's shared key, not a secret")
        base = base_latency = None
        for i, (label, spec) in enumerate(cases):
            case_backend = netem_lab.backend_for(spec, netem=backend == "netem")
            if "nfqueue" in case_backend and no_queue:
                results["cases"].append({"case": label, "netem": spec, "run": False,
                                         "why": f"needs tc netem or the NFQUEUE delay line ({no_queue})"})
                print(f"{label:32s} not run: {no_queue}", flush=True)
                continue
            t0 = time.monotonic()
            r = netem_lab.run_case(work / f"c{i}", spec, duration=args.duration, rate=args.rate,
                                   scenario=args.scenario, port=7741 + i, tag=str(i), backend=case_backend,
                                   auth_key=key if "auth" in label else None, seed=1 + 2 * i)
            r["case"], r["run"], r["wall_s"] = label, True, time.monotonic() - t0
            if base is None:
                base = r["result"]["max_sigma_BD_after_10s"]
                base_latency = r["latency_us"]["p50"]
            # the added latency as the emulator saw it (state published -> its command received)
            r["latency_us"]["added_p50"] = r["latency_us"]["p50"] - base_latency if base_latency is not None else None
            r["result"]["worst_error_vs_clean"] = (r["result"]["max_sigma_BD_after_10s"] / base
                                                   if base else None)
            results["cases"].append(r)
            c = r["checks"]
            ok = (c['to_controller']['lost_ok'] and c['to_emulator']['lost_ok']
                  and c['to_controller']['dup_ok'] and c['to_emulator']['dup_ok'])
            print(f"{label:32s} lost to ctl {c['to_controller']['lost']:4d} "
                  f"(exp {c['to_controller']['lost_expected'][0]:.0f}-{c['to_controller']['lost_expected'][1]:.0f}) "
                  f"to emu {c['to_emulator']['lost']:4d}  dup {c['to_controller']['duplicates']}/"
                  f"{c['to_emulator']['duplicates']}  ok {ok}  "
                  f"hold {r['stale']['controller_stale_steps']} SAFE rows {r['stale']['rows_safe']}  "
                  f"bound {'held' if r['result']['first_bound_violation_s'] is None else 'LOST'}  "
                  f"worst |sigma_BD| x{r['result']['worst_error_vs_clean'] or 0:.3f}  "
                  f"latency p50/p99 {r['latency_us']['p50']:.0f}/{r['latency_us']['p99']:.0f} us", flush=True)
            if "delay_line" in r:
                dl = r["delay_line"]
                for side in ("to_controller", "to_emulator"):
                    k, d = dl["checks"][side], dl[side]
                    print(f"  {side:14s} delayed {k['delayed']} (delay p50/p99 {d['delay_us']['p50']:.0f}/"
                          f"{d['delay_us']['p99']:.0f} us, line late p99 {d['lateness_us']['p99']:.0f} us), "
                          f"out of order: delay line {k['delay_line_out_of_order']} log {k['log_out_of_order']} "
                          f"counted {k['counted_out_of_order']} (+-{k['edge']}), expected "
                          f"{k['expected']:.1f} +- {k['expected_tol']:.1f} ({'ok' if k['expected_ok'] else 'OUT'})",
                          flush=True)
                print("  all channels: " + ", ".join(
                    f"{side} {dl[side]['all_channels']['left_out_of_order']} of {dl[side]['all_channels']['datagrams']}"
                    f" left out of order ({dl[side]['all_channels']['sent_at_once']} at once)"
                    for side in ("to_controller", "to_emulator")), flush=True)
        # the PD loop's margins at the loop latencies the delay cases measured
        # (state published to command received: both directions and the step)
        measured = sorted({round(c["latency_us"][q] / 1e6, 4) for c in results["cases"]
                           if c.get("run") and c["expected"]["delay_ms"] for q in ("p50", "p99")})
        latencies = (measured[:1] or [0.002]) if args.smoke else (1e-6, 0.002, 0.003, *measured)
        results["design"] = [design_margins(args.scenario, lat, work) for lat in latencies]
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2, default=float) + "\n")
    print(f"bench_netem: {out}")
    for d in results["design"]:
        print(f"  sc-rt design --latency {d['latency_s']:g}: min phase margin {d['min_phase_margin_deg']:.3f} deg, "
              f"min delay margin {d['min_delay_margin_s']:.3f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
