"""sc-rt hil --live: does serving the bus to a client slow the loop? A
1 kHz real-time run (paper_faults) three ways, interleaved: without
--live, with --live and no client, with --live and a Foxglove WebSocket
client subscribed to every topic (tests/fgclient.py: the decimated 50 Hz
stream of each channel, the derived topics). Per run: the state-to-command
latency p99 and the freshness (timing.json ``fresh_fraction``: the share
of ticks that applied the answer to the state of the tick before), and the
messages the client got; the median of the runs per way. Runs in a
private network namespace when root.

    .venv/bin/python bench/bench_live.py [--quick | --smoke]

(full: 3 runs of 20 s per way; --quick: 3 of 5 s; --smoke: 1 of 1 s, a
check that it runs.)
"""

from __future__ import annotations

import json
import socket
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from common import HIL_MEASURE, ROOT, hil_timing, machine, mode, write

sys.path.insert(0, str(ROOT / "tests"))
import lcmnet  # noqa: E402

WAYS = ("no_live", "live_no_client", "live_client")


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def run(way: str, duration: float) -> dict:
    """One 1 kHz real-time run: its latency p99, freshness, misses (and the client's messages)."""
    with tempfile.TemporaryDirectory() as d:
        out = Path(d) / "hil"
        hil = ["hil", "scenarios/paper_faults.toml", "--mode", "realtime", "--control-rate", "1000",
               "--duration", str(duration), "--no-plots", "--out", str(out), *HIL_MEASURE]
        got = {}
        if way == "no_live":
            cmd = [sys.executable, "-m", "sc_rt.cli", *hil]
        else:
            port = _port()
            cmd = [sys.executable, str(ROOT / "tests" / "fgclient.py"), "--port", str(port), "--out",
                   str(Path(d) / "client.json"), "--timeout", str(60 + 2 * duration),
                   *(["--no-client"] if way == "live_no_client" else []), "--", *hil, "--live", str(port)]
        r = subprocess.run(lcmnet.wrap(cmd), capture_output=True, text=True, cwd=ROOT, timeout=600)
        rc, err = r.returncode, r.stderr
        if way != "no_live":
            if rc != 0:
                raise RuntimeError(f"{way}: {r.stderr[-2000:]}")
            got = json.loads((Path(d) / "client.json").read_text())
            if "live on" not in (got.get("live_line") or ""):
                raise RuntimeError(f"{way}: {got.get('error')} {got.get('hil_stderr', '')[-2000:]}")
            rc, err = got.get("hil_rc"), f"{got.get('error')} {got.get('hil_stderr', '')}"
        t = hil_timing(rc, out, way, err)
    res = {"latency_p99_us": t["state_to_cmd_latency_us"]["p99"],
           "latency_p50_us": t["state_to_cmd_latency_us"]["p50"],
           "fresh_fraction": t["fresh_fraction"], "deadline_misses": t["deadline_misses"], "steps": t["steps"],
           "kept_real_time": t.get("kept_real_time")}
    if way == "live_client":
        res["client_messages"] = sum(len(v) for v in got.get("messages", {}).values())
        res["client_states"] = len(got.get("messages", {}).get("SCRT_STATE", []))
    return res


def main(size: str = "full") -> None:
    duration = {"smoke": 1, "quick": 5}.get(size, 20)
    runs = 1 if size == "smoke" else 3
    res: dict = {"machine": machine(), "scenario": "paper_faults", "rate_hz": 1000, "duration_s": duration,
                 "netns": lcmnet.can_unshare(), "runs": {w: [] for w in WAYS}}
    for _ in range(runs):  # interleaved: the machine drifts
        for way in WAYS:
            res["runs"][way].append(run(way, duration))
    for way in WAYS:
        rs = res["runs"][way]
        res[way] = {k: statistics.median(r[k] for r in rs) for k in rs[0]}
    base = res["no_live"]
    for way in WAYS[1:]:
        res[f"{way}_p99_over_no_live"] = res[way]["latency_p99_us"] / base["latency_p99_us"]
    write("live", res)
    print(f"\n{'way':<16}{'p99 [us]':>10}{'p50 [us]':>10}{'fresh':>8}{'misses':>8}   (median of {runs})")
    for way in WAYS:
        m = res[way]
        print(f"{way:<16}{m['latency_p99_us']:>10.1f}{m['latency_p50_us']:>10.1f}{m['fresh_fraction']:>8.4f}"
              f"{m['deadline_misses']:>8.0f}")


if __name__ == "__main__":
    main(mode())
