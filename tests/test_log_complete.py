"""A log that lacks messages of its run says so: ``log_missing`` counts, per
channel the emulator publishes once per row, the rows the log does not hold."""

from __future__ import annotations

import lcm
import sc_rt_lcm

from sc_rt.logs.timing import log_missing


def _write(path, seqs_state, seqs_truth, seqs_guidance=(), prefix=""):
    log = lcm.EventLog(str(path), "w", overwrite=True)
    t = 0
    for ch, cls, seqs in (("SCRT_STATE", sc_rt_lcm.plant_state_t, seqs_state),
                          ("SCRT_TRUTH", sc_rt_lcm.plant_truth_t, seqs_truth),
                          ("SCRT_GUIDANCE", sc_rt_lcm.guidance_t, seqs_guidance)):
        for k in seqs:
            m = cls()
            m.seq = k
            t += 1
            log.write_event(t, prefix + ch, m.encode())
    log.close()


def test_a_complete_log_misses_nothing(tmp_path):
    p = tmp_path / "ok.lcmlog"
    _write(p, range(10), range(10), range(10))
    assert log_missing(p, "", 10) == {"SCRT_STATE": 0, "SCRT_TRUTH": 0, "SCRT_GUIDANCE": 0}


def test_missing_and_resent_states_are_counted_by_row(tmp_path):
    p = tmp_path / "gaps.lcmlog"
    # state 3 re-sent twice (one row), states 5 and 7 lost, truth 9 lost, no guidance at all
    _write(p, [0, 1, 2, 3, 3, 3, 4, 6, 8, 9], [k for k in range(10) if k != 9], prefix="B_")
    assert log_missing(p, "B_", 10) == {"SCRT_STATE": 2, "SCRT_TRUTH": 1, "SCRT_GUIDANCE": 0}
    # another bench's prefix is not this run's
    assert log_missing(p, "", 10) == {"SCRT_STATE": 10, "SCRT_TRUTH": 10, "SCRT_GUIDANCE": 0}
