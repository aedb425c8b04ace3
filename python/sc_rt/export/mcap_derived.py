"""Derived channels of ``sc-rt export`` (JSON rows, vectorised over a batch):
the frames B and D relative to N as ``foxglove.FrameTransform``, the
pointing error against the prescribed bound (the true error, the law's and
the knowledge error, each named), the wheel speeds, the law's telemetry by
name; and their JSON schemas (Foxglove's well-known one for the frames)."""

from __future__ import annotations

import json
import math
from itertools import islice

import numpy as np

__all__ = ["ARCSEC", "FOXGLOVE_SCHEMAS", "POINTING_SCHEMA", "WHEELS_SCHEMA", "TELEMETRY_SCHEMA", "Deriver",
           "Truth", "mrp_to_quaternion", "frame_messages", "pointing_messages", "wheel_messages",
           "telemetry_messages", "derived_topics", "derive_order", "pointing_topic"]

#: [arcsec / rad]
ARCSEC = 180.0 / math.pi * 3600.0
RPM = 60.0 / (2.0 * math.pi)

_XYZ = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"},
        "required": list("xyz")}
_TIME = {"type": "object", "title": "time",
         "properties": {"sec": {"type": "integer", "minimum": 0},
                        "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}},
         "required": ["sec", "nsec"]}
#: Foxglove's well-known schemas used here (JSON encoding), as Foxglove defines them
FOXGLOVE_SCHEMAS = {
    "foxglove.FrameTransform": {
        "title": "foxglove.FrameTransform", "description": "A transform between two reference frames in 3D space",
        "type": "object",
        "properties": {
            "timestamp": {**_TIME, "description": "Timestamp of transform"},
            "parent_frame_id": {"type": "string", "description": "Name of the parent frame"},
            "child_frame_id": {"type": "string", "description": "Name of the child frame"},
            "translation": {**_XYZ, "title": "foxglove.Vector3",
                            "description": "Translation component of the transform"},
            "rotation": {"title": "foxglove.Quaternion", "type": "object",
                         "properties": {k: {"type": "number"} for k in "xyzw"}, "required": list("xyzw"),
                         "description": "Rotation component of the transform"},
        },
        "required": ["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"],
    },
}
_AX = {"type": "object", "properties": {k: {"type": "number"} for k in "xyz"}, "required": list("xyz")}
POINTING_SCHEMA = {
    "title": "sc_rt.pointing",
    "description": "Pointing error of B relative to D, one row per controller_status_t, each error named: "
                   "true_* the truth against the reference (plant_state_t.sigma_BN of the state the status "
                   "answers, state_seq, against the status's sigma_DN; absent when the log has no such "
                   "state); law_* the law's own (the status's sigma_BD: what it computed from its "
                   "measurement, the estimate when it is fed one, else the truth: then the true error "
                   "again); knowledge_* the truth against the estimate (sigma_BN_est; only when the "
                   "controller runs the estimator). And the prescribed bound of the logged "
                   "controller_config_t (bound fields absent before a config is in the log)",
    "type": "object",
    "properties": {
        "t": {"type": "number", "description": "[s] simulation time"},
        "mode": {"type": "integer", "description": "wheel_cmd_t.MODE_*: 0 INIT, 1 NORMAL, 2 SAFE"},
        "true_error_arcsec": {"type": "number", "description": "[arcsec] true pointing error 4 atan |sigma_BD|, "
                              "sigma_BD = sigma_BN (-) sigma_DN of the truth (8)"},
        "true_sigma_BD_arcsec": {**_AX, "description": "[arcsec] 4 atan sigma_BD,i per axis, the truth's"},
        "law_error_arcsec": {"type": "number", "description": "[arcsec] the law's pointing error 4 atan "
                             "|controller_status_t.sigma_BD| (from its estimate when fed one)"},
        "law_sigma_BD_arcsec": {**_AX, "description": "[arcsec] 4 atan sigma_BD,i per axis, the law's"},
        "knowledge_error_arcsec": {"type": "number", "description": "[arcsec] knowledge error 4 atan |sigma|, "
                                   "sigma the MRP of the truth B relative to the estimate"},
        "knowledge_sigma_arcsec": {**_AX, "description": "[arcsec] 4 atan sigma_i per axis, the knowledge error's"},
        "bound_upper_arcsec": {**_AX, "description": "[arcsec] 4 atan(dmax chi(t)) per axis"},
        "bound_lower_arcsec": {**_AX, "description": "[arcsec] -4 atan(dmin chi(t)) per axis"},
        "chi": {**_AX, "description": "[-] prescribed envelope chi(t) of (29), _core.ppc_chi"},
        "bound_ok": {"type": "boolean", "description": "-dmin chi < sigma_BD < dmax chi on every axis, sigma_BD "
                     "the true error (absent without it)"},
    },
    "required": ["t", "mode", "law_error_arcsec", "law_sigma_BD_arcsec"],
}
WHEELS_SCHEMA = {
    "title": "sc_rt.wheels", "description": "Reaction wheel speeds from plant_state_t", "type": "object",
    "properties": {
        "t": {"type": "number", "description": "[s] simulation time"},
        "speed_rad_s": {"type": "object", "properties": {f"w{i}": {"type": "number"} for i in range(1, 5)},
                        "required": [f"w{i}" for i in range(1, 5)], "description": "[rad/s]"},
        "speed_rpm": {"type": "object", "properties": {f"w{i}": {"type": "number"} for i in range(1, 5)},
                      "required": [f"w{i}" for i in range(1, 5)], "description": "[rpm]"},
    },
    "required": ["t", "speed_rad_s", "speed_rpm"],
}

_NUM = {"type": "number", "description": "(null: not finite)"}
TELEMETRY_SCHEMA = {
    "title": "sc_rt.law_telemetry",
    "description": "The control law's telemetry from controller_status_t: the fixed slots and its named values, "
                   "values[i] named names[i] (the run's start record, SCRT_HIL_START telemetry_names; "
                   "'telemetry[i]' where the log has none); null: not finite, or not recorded (a log written "
                   "before the law's telemetry was on the bus)",
    "type": "object",
    "properties": {
        "t": {"type": "number", "description": "[s] simulation time"},
        **{k: {"type": "object", "title": "xyz", "properties": {a: _NUM for a in "xyz"}, "required": list("xyz"),
               "description": f"LawOutput.{k}"} for k in ("e1", "e2", "z1", "z2", "x2d")},
        "vs": {"type": "array", "items": _NUM, "minItems": 4, "maxItems": 4,
               "description": "LawOutput.vs, the anti-windup state"},
        "rho_hat": {**_NUM, "description": "LawOutput.rho_hat, an adaptive gain (null: not finite)"},
        "names": {"type": "array", "items": {"type": "string"},
                  "description": "the named values' names, 'name [unit]' as the law declared them"},
        "values": {"type": "array", "items": _NUM, "description": "the named values, in the order of names"},
    },
    "required": ["t", "e1", "e2", "z1", "z2", "x2d", "vs", "rho_hat", "names", "values"],
}


def _finite(v: float) -> float | None:
    return v if math.isfinite(v) else None


def telemetry_messages(rec, names: tuple[str, ...]) -> list[bytes | None]:
    """sc_rt.law_telemetry rows of controller_status_t records (None where t
    is not finite); ``names``: the law's telemetry names (from the start record)."""
    out: list[bytes | None] = []
    fields = rec.dtype.names or ()
    n_tel = rec["n_telemetry"].astype(int).tolist() if "n_telemetry" in fields else [0] * len(rec)
    for k, t in enumerate(np.asarray(rec["t"], float).tolist()):
        if not math.isfinite(t):
            out.append(None)
            continue
        row: dict = {"t": t}
        for name in ("e1", "e2", "z1", "z2", "x2d"):
            row[name] = dict(zip("xyz", map(_finite, np.asarray(rec[name][k], float).tolist())))
        row["vs"] = [_finite(v) for v in np.asarray(rec["vs"][k], float).tolist()]
        row["rho_hat"] = _finite(float(rec["rho_hat"][k]))
        vals = np.asarray(rec["telemetry"][k], float).tolist()
        n = max(0, min(n_tel[k], len(vals)))
        row["names"] = [names[i] if i < len(names) else f"telemetry[{i}]" for i in range(n)]
        row["values"] = [_finite(v) for v in vals[:n]]
        out.append(json.dumps(row, separators=(",", ":")).encode())
    return out


def mrp_to_quaternion(sigma: np.ndarray) -> np.ndarray:
    """(x, y, z, w) Hamilton quaternions of the rotation from parent N to
    child B for MRPs sigma_BN, shape (n, 3) -> (n, 4): the Euler parameters
    of sigma (w = (1 - |s|^2) / (1 + |s|^2), v = 2 s / (1 + |s|^2)); their
    rotation matrix is [NB] = R(sigma)^T (B components to N)."""
    s = np.asarray(sigma, float).reshape(-1, 3)
    with np.errstate(all="ignore"):  # hostile values give non-finite rows, left out by the callers
        s2 = np.sum(s * s, axis=1, keepdims=True)
        return np.hstack([2.0 * s / (1.0 + s2), (1.0 - s2) / (1.0 + s2)])



def frame_messages(sigma, stamps_us: list[int], parent: str, child: str) -> list[bytes | None]:
    """One foxglove.FrameTransform per MRP row (None where not finite)."""
    sigma = np.asarray(sigma, float).reshape(-1, 3)
    q = mrp_to_quaternion(sigma)
    ok = np.isfinite(q).all(axis=1).tolist()
    pre = ('{"timestamp":{"sec":%d,"nsec":%d},"parent_frame_id":' + json.dumps(parent).replace("%", "%%")
           + ',"child_frame_id":' + json.dumps(child).replace("%", "%%")
           + ',"translation":{"x":0.0,"y":0.0,"z":0.0},"rotation":{"x":%r,"y":%r,"z":%r,"w":%r}}')
    out: list[bytes | None] = []
    for good, ts, (x, y, z, w) in zip(ok, stamps_us, q.tolist()):
        if not good:
            out.append(None)
            continue
        ts = max(int(ts), 0)
        out.append((pre % (ts // 1_000_000, ts % 1_000_000 * 1000, x, y, z, w)).encode())
    return out


def _xyz(v) -> str:
    return '{"x":%r,"y":%r,"z":%r}' % (v[0], v[1], v[2])


def pointing_messages(t, mode, sigma_BD, ppc, sigma_BD_true=None, knowledge=None) -> list[bytes | None]:
    """sc_rt.pointing rows of the law's errors ``sigma_BD`` (controller_status_t),
    with, where given and finite, the true errors ``sigma_BD_true`` and the
    knowledge errors ``knowledge`` (MRPs, rows); the bound fields need ``ppc``
    (_core.PpcParams of the logged controller_config_t), else they are left out."""
    with np.errstate(all="ignore"):  # hostile values: non-finite rows, left out
        return _pointing(t, mode, sigma_BD, ppc, sigma_BD_true, knowledge)


def _angles(sigma, n: int) -> tuple[np.ndarray, np.ndarray, list[bool]]:
    """(4 atan|sigma| per row, 4 atan sigma_i per axis [arcsec], finite per row) of MRP rows (NaN: none)."""
    s = np.full((n, 3), np.nan) if sigma is None else np.asarray(sigma, float).reshape(-1, 3)
    return (4.0 * np.arctan(np.linalg.norm(s, axis=1)) * ARCSEC, 4.0 * np.arctan(s) * ARCSEC,
            np.isfinite(s).all(axis=1).tolist())


def _pointing(t, mode, sigma_BD, ppc, sigma_BD_true, knowledge) -> list[bytes | None]:
    from sc_rt import _core

    t = np.asarray(t, float)
    n = len(t)
    err, ax, ok = _angles(sigma_BD, n)
    true_err, true_ax, has_true = _angles(sigma_BD_true, n)
    kn_err, kn_ax, has_kn = _angles(knowledge, n)
    ok = (np.isfinite(t) & np.asarray(ok, bool)).tolist()
    chi = up = lo = inside = None
    if ppc is not None:
        chi = np.array([_core.ppc_chi(ppc, float(tk)) if math.isfinite(tk) else [np.nan] * 3
                        for tk in t.tolist()]).reshape(-1, 3)
        dmin, dmax = np.asarray(ppc.dmin, float), np.asarray(ppc.dmax, float)
        up = 4.0 * np.arctan(dmax * chi) * ARCSEC
        lo = -4.0 * np.arctan(dmin * chi) * ARCSEC
        s = np.full((n, 3), np.nan) if sigma_BD_true is None else np.asarray(sigma_BD_true, float).reshape(-1, 3)
        inside = np.all((s > -dmin * chi) & (s < dmax * chi), axis=1).tolist()  # judged on the true error
        ok = (np.asarray(ok) & np.isfinite(chi).all(axis=1)).tolist()
    out: list[bytes | None] = []
    modes = np.asarray(mode).astype(int).tolist()
    for k, good in enumerate(ok):
        if not good:
            out.append(None)
            continue
        body = '{"t":%r,"mode":%d' % (float(t[k]), modes[k])
        if has_true[k]:
            body += ',"true_error_arcsec":%r,"true_sigma_BD_arcsec":%s' % (float(true_err[k]),
                                                                          _xyz(true_ax[k].tolist()))
        body += ',"law_error_arcsec":%r,"law_sigma_BD_arcsec":%s' % (float(err[k]), _xyz(ax[k].tolist()))
        if has_kn[k]:
            body += ',"knowledge_error_arcsec":%r,"knowledge_sigma_arcsec":%s' % (float(kn_err[k]),
                                                                                 _xyz(kn_ax[k].tolist()))
        if chi is not None:
            body += ',"bound_upper_arcsec":%s,"bound_lower_arcsec":%s,"chi":%s' % (
                _xyz(up[k].tolist()), _xyz(lo[k].tolist()), _xyz(chi[k].tolist()))
            if has_true[k]:
                body += ',"bound_ok":%s' % ("true" if inside[k] else "false")
        out.append((body + "}").encode())
    return out


def wheel_messages(t, speed) -> list[bytes | None]:
    """sc_rt.wheels rows (None where not finite)."""
    t = np.asarray(t, float)
    w = np.asarray(speed, float).reshape(-1, 4)
    with np.errstate(all="ignore"):
        r = w * RPM
    ok = (np.isfinite(t) & np.isfinite(w).all(axis=1) & np.isfinite(r).all(axis=1)).tolist()
    rpm = r.tolist()
    fmt = ('{"t":%r,"speed_rad_s":{"w1":%r,"w2":%r,"w3":%r,"w4":%r},'
           '"speed_rpm":{"w1":%r,"w2":%r,"w3":%r,"w4":%r}}')
    return [(fmt % (tk, *wk, *rk)).encode() if good else None
            for good, tk, wk, rk in zip(ok, t.tolist(), w.tolist(), rpm)]


def derive_order(channel: str | bytes) -> tuple[bool, bool, bool]:
    """The sort key of a batch's channels for the derived topics: the
    configurations first (the pointing's bound), then guidance (frame D),
    then the plant's states (the pointing's truth), then the rest."""
    c = channel.encode() if isinstance(channel, str) else bytes(channel)
    return (not c.endswith(b"SCRT_CONFIG"), not c.endswith(b"SCRT_GUIDANCE"), not c.endswith(b"SCRT_STATE"))


class Truth:
    """The plant's true attitudes of one bench by state (plant_state_t seq,
    with its time): what the true pointing error of a controller_status_t
    (its state_seq and t) is computed from. The newest ``KEEP`` states at
    most, the newest half of them kept when there are more: more than the
    states of one batch of the export (a status answers a state of the last
    few control periods, and a batch's states are read before its statuses)."""

    KEEP = 1 << 16

    def __init__(self):
        self.by_seq: dict[int, tuple[float, float, float, float]] = {}

    def add(self, rec) -> None:
        """The states of plant_state_t records."""
        d = self.by_seq
        for q, tk, sk in zip(np.asarray(rec["seq"]).astype(np.int64).tolist(), np.asarray(rec["t"], float).tolist(),
                             np.asarray(rec["sigma_BN"], float).reshape(-1, 3).tolist()):
            d[q] = (tk, *sk)
        if len(d) > self.KEEP:  # the oldest half goes (insertion order)
            for q in list(islice(d, len(d) - self.KEEP // 2)):
                del d[q]

    def sigma_BN(self, state_seq, t) -> np.ndarray:
        """sigma_BN (rows) of the states ``state_seq`` at times ``t``; NaN
        where none is known (not seen, or a state of that seq at another time:
        another run's)."""
        t = np.asarray(t, float)
        out = np.full((len(t), 3), np.nan)
        d = self.by_seq
        for k, (q, tk) in enumerate(zip(np.asarray(state_seq).astype(np.int64).tolist(), t.tolist())):
            v = d.get(q)
            if v is not None and v[0] == tk:
                out[k] = v[1:]
        return out


def _root(prefix: str) -> str:
    """The folder of a bench's derived topics: /derived, or /derived/<prefix> for a prefixed bench."""
    p = prefix.strip("_/.")
    return "/derived" + ("/" + p if p else "")


def pointing_topic(prefix: str) -> str:
    """The pointing topic of the bench of channel prefix ``prefix``."""
    return _root(prefix) + "/pointing"


def derived_topics(type_name: str, prefix: str) -> list[tuple[str, dict]]:
    """(topic, schema) of the derived channels the messages of a type feed
    (as Deriver.messages gives them), for a bench of channel prefix ``prefix``."""
    tf = ("/tf", FOXGLOVE_SCHEMAS["foxglove.FrameTransform"])
    return {"plant_state_t": [tf, (_root(prefix) + "/wheels", WHEELS_SCHEMA)],
            "guidance_t": [tf],
            "controller_status_t": [tf, (pointing_topic(prefix), POINTING_SCHEMA),
                                    (_root(prefix) + "/telemetry", TELEMETRY_SCHEMA)]}.get(type_name, [])


class Deriver:
    """Which derived messages the decoded records of one channel give, per
    bench (channel prefix): frame B and the wheels from plant_state_t;
    frame D from guidance_t where the log has it (it comes first in each
    step), else from controller_status_t; the pointing from the status (the
    law's error, and the knowledge error when it runs the estimator) and the
    state it answers (the true error: ``Truth``, fed by ``states``), with
    the bound of the bench's first controller_config_t."""

    def __init__(self):
        self.ppc: dict[str, object] = {}  # prefix -> _core.PpcParams
        self.names: dict[str, tuple[str, ...]] = {}  # prefix -> the law's telemetry names
        self.truth: dict[str, Truth] = {}  # prefix -> the plant's attitudes by state
        self.guidance: set[str] = set()
        self.rejected_configs = 0
        #: prefix -> its wheels take motor torques [N m] (controller_config_t's wheel_torque_command)
        self.torque: dict[str, bool] = {}

    def states(self, prefix: str, rec) -> None:
        """The true attitudes of a bench's plant_state_t records (every one,
        whether its own topics are sent or not: the true pointing error)."""
        if len(rec):
            self.truth.setdefault(prefix, Truth()).add(rec)

    def _errors(self, prefix: str, rec) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(true tracking errors, knowledge errors) of controller_status_t
        records, as MRP rows (NaN where the state is unknown; knowledge: where
        the controller runs no estimator); (None, None) without any state."""
        from sc_rt.results.judge.estimation import mrp_subtract_rows

        truth = self.truth.get(prefix)
        if truth is None:
            return None, None
        with np.errstate(all="ignore"):
            s_bn = truth.sigma_BN(rec["state_seq"], rec["t"])
            true = mrp_subtract_rows(s_bn, rec["sigma_DN"])  # (8): B relative to D, the truth's
            know = None
            if "nav" in (rec.dtype.names or ()):
                know = mrp_subtract_rows(s_bn, rec["sigma_BN_est"])  # the truth relative to the estimate
                know[~np.asarray(rec["nav"], bool)] = np.nan
        return true, know

    def config(self, prefix: str, data: bytes, latest: bool = False) -> None:
        """The bound and the wheels' command unit of a bench from its
        controller_config_t: the first one (a log), or with ``latest`` the
        newest (a live bus, run after run)."""
        if prefix in self.ppc and not latest:
            return
        from sc_rt import _core

        try:
            cfg = _core.ControllerConfig.from_lcm_bytes(bytes(data))
            self.ppc[prefix] = cfg.ppc
            self.torque[prefix] = bool(cfg.spacecraft.wheel_torque_command)
        except (ValueError, RuntimeError, TypeError):
            self.rejected_configs += 1

    def start(self, prefix: str, record: dict | None) -> None:
        """The names of a bench's law telemetry, from its run's start record (SCRT_HIL_START)."""
        names = (record or {}).get("telemetry_names") or ()
        if isinstance(names, list) and all(isinstance(x, str) for x in names):
            self.names[prefix] = tuple(names)

    def messages(self, type_name: str, prefix: str | None, rec, stamps: list[int]) -> list[tuple]:
        """[(counter, topic, schema, one message or None per record)]."""
        if prefix is None or not len(rec):
            return []
        p = prefix
        root = _root(p)
        tf = FOXGLOVE_SCHEMAS["foxglove.FrameTransform"]
        if type_name == "plant_state_t":
            self.states(p, rec)
            return [("frame_B", "/tf", tf, frame_messages(rec["sigma_BN"], stamps, p + "N", p + "B")),
                    ("wheels", root + "/wheels", WHEELS_SCHEMA, wheel_messages(rec["t"], rec["wheel_speed"]))]
        if type_name == "guidance_t":
            self.guidance.add(p)
            return [("frame_D", "/tf", tf, frame_messages(rec["sigma_DN"], stamps, p + "N", p + "D"))]
        if type_name == "controller_status_t":
            out = [] if p in self.guidance else [
                ("frame_D", "/tf", tf, frame_messages(rec["sigma_DN"], stamps, p + "N", p + "D"))]
            true, know = self._errors(p, rec)
            return out + [("pointing", pointing_topic(p), POINTING_SCHEMA,
                           pointing_messages(rec["t"], rec["mode"], rec["sigma_BD"], self.ppc.get(p), true, know)),
                          ("telemetry", root + "/telemetry", TELEMETRY_SCHEMA,
                           telemetry_messages(rec, self.names.get(p, ())))]
        return []
