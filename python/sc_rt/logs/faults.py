"""The fault commands of a log and what the plant made of them, for
``sc-rt report`` (logs/report.py): the commands seen on SCRT_FAULT and
SCRT_ROD_FAULT, each marked applied or refused by the seqs the emulator's
truth echoes (``plant_truth_t.fault_seq_applied`` / ``fault_seq_refused``),
and the fault state changes the truth shows, the wheels' and the rods'."""

from __future__ import annotations

from typing import Any

import numpy as np

from sc_rt.logs.logread import LogData
from sc_rt.logs.rebuild import Rebuilt
from sc_rt.model.rods import ROD_FAULTS

__all__ = ["fault_summary", "MAX_FAULT_CHANGES"]

#: fault state changes listed per wheel in report.json (a hostile log could have one per row)
MAX_FAULT_CHANGES = 1000
#: rod_fault_cmd_t.kind -> the fault's name (model.rods.ROD_FAULTS)
_ROD_KINDS = {v: k for k, v in ROD_FAULTS.items()}


def fault_summary(d: LogData, r: Rebuilt) -> dict[str, Any]:
    """Fault commands seen on the bus, the wheels' (``"wheel"``) and then the
    rods' (``"rod"``: rod_fault_cmd_t on SCRT_ROD_FAULT), and the fault state
    changes in plant_truth_t (when the emulator applied them): the wheels'
    (``state_changes``) and the rods' (``rod_state_changes``: the fault's
    kind and whether it is active; none in a log of the older layout)."""
    st = r.arrays["state_log_us"]
    t = r.arrays["t"]
    t0 = int(st[0]) if st.size else 0
    cmds = []
    for base, fields in (("SCRT_FAULT", lambda rec: {
            "wheel": int(rec["wheel"]), "effectiveness": float(rec["effectiveness"]), "bias": float(rec["bias"]),
            "rate": float(rec["rate"]), "stuck": bool(rec["stuck"]), "friction": float(rec["friction"])}),
            ("SCRT_ROD_FAULT", lambda rec: {
                "rod": int(rec["rod"]), "kind": _ROD_KINDS.get(int(rec["kind"]), int(rec["kind"])),
                "dipole": float(rec["dipole"])})):
        for rec, stamp in zip(d.records[base], d.stamps[base]):
            k = int(np.searchsorted(st, stamp, side="right")) - 1  # newest state logged before it
            cmds.append({"log_s": (int(stamp) - t0) / 1e6, "t_sim_at_receipt": float(t[k]) if k >= 0 else None,
                         "seq": int(rec["seq"]),
                         "action": {1: "inject", 2: "clear"}.get(int(rec["action"]), int(rec["action"])),
                         "now": bool(rec["now"]), "t_onset": float(rec["t_onset"]), "t_end": float(rec["t_end"]),
                         **fields(rec)})
    _mark_answers(cmds, d.records["SCRT_TRUTH"])
    changes: list[dict[str, Any]] = []
    h = r.has_truth
    L, B, K, Y = (r.arrays[k][h] for k in ("fault_effectiveness", "fault_bias", "fault_stuck", "fault_Y"))
    th = t[h]
    active_from: list[float | None] = []
    for w in range(4):
        cur = np.stack([L[:, w], B[:, w], K[:, w].astype(float)], axis=1)
        healthy = np.array([1.0, 0.0, 0.0])
        prev = np.vstack([healthy, cur[:-1]]) if th.size else cur
        idx = np.nonzero(np.any(cur != prev, axis=1))[0]
        for i in idx[:MAX_FAULT_CHANGES]:
            changes.append({"t": float(th[i]), "wheel": w + 1, "effectiveness": float(L[i, w]),
                            "bias": float(B[i, w]), "stuck": bool(K[i, w])})
        on = np.nonzero(Y[:, w] > 0)[0]
        active_from.append(float(th[on[0]]) if on.size else None)
    changes.sort(key=lambda c: (c["t"], c["wheel"]))
    return {"commands": cmds, "state_changes": changes, "first_active_s": active_from,
            "rod_state_changes": _rod_changes(r)}


def _mark_answers(cmds: list[dict[str, Any]], T: np.ndarray) -> None:
    """Each fault command's ``applied``, from the seqs the truth echoes (the
    newest fault command applied, ``fault_seq_applied``, and refused,
    ``fault_seq_refused``, as each row starts): True when a truth names its
    seq as applied; False with ``refused`` True when one names it as
    refused (the plant could not apply it); False with ``refused`` False
    when no truth names it nor any later command (no emulator of the log
    applied it: another session's, one ignoring fault commands); None when
    a later command's seq is named instead (both arrived within one row: the
    log cannot tell) and for a log whose truth does not say (the older
    layout: both fields 0 in every message, where an emulator that says
    says -1 before its first fault command)."""
    said = T.size and bool(np.any(T["fault_seq_applied"] != 0) or np.any(T["fault_seq_refused"] != 0))
    applied = set(np.unique(T["fault_seq_applied"]).tolist()) if said else set()
    refused = set(np.unique(T["fault_seq_refused"]).tolist()) if said else set()
    newest = max(applied | refused) if said else -1
    for c in cmds:
        if not said or (c["seq"] not in applied | refused and newest > c["seq"]):
            c["applied"] = None
        else:
            c["applied"] = c["seq"] in applied
            if not c["applied"]:
                c["refused"] = c["seq"] in refused


def _rod_changes(r: Rebuilt) -> list[dict[str, Any]]:
    """The rods' fault state changes (plant_truth_t ``rod_fault``), in time
    order: ``fault`` the kind (None: healthy), ``active`` whether at t."""
    if r.rods is None:
        return []
    h = r.has_truth
    F, th = r.rods["rod_fault"][h], r.arrays["t"][h]
    out = []
    for i in range(6):
        prev = np.concatenate(([0], F[:-1, i]))
        for j in np.nonzero(F[:, i] != prev)[0][:MAX_FAULT_CHANGES]:
            v = int(F[j, i])
            out.append({"t": float(th[j]), "rod": i + 1, "fault": _ROD_KINDS.get(abs(v)), "active": v > 0})
    out.sort(key=lambda c: (c["t"], c["rod"]))
    return out
