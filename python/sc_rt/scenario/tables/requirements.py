"""The ``[[requirements]]`` rows of a scenario: what a run is judged by
(docs/REQUIREMENTS.md, docs/SCENARIOS.md).

Each row names one requirement: a pointing index of ECSS-E-ST-60-10C (APE,
MPE, RPE, PDE, PRE on the performance error; AKE, MKE, RKE, KDE, KRE on the
knowledge error), a settling time, a wheel speed margin, a wheel momentum
margin, a bound on the commanded wheel acceleration, or the
prescribed-performance envelope of ``[controller.ppc]``.
This module only reads and validates the rows (file, line, key, value);
``sc_rt.results.judge.requirements`` evaluates them on a run.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from sc_rt.scenario.schema import Spec, Table, format_value

__all__ = ["ANGLE_UNITS", "AXES", "COUNTERPART", "INTERPRETATIONS", "KINDS", "KNOWLEDGE", "MODES", "PAIRED",
           "PERFORMANCE",
           "UNITS", "WINDOWED", "Requirement", "read_requirements", "requirements_data"]

#: ECSS performance indices (the truth against the reference) and knowledge
#: indices (the estimate against the truth); the windowed ones need
#: ``window``, the paired ones (drift, reproducibility) ``separation`` too.
PERFORMANCE = ("APE", "MPE", "RPE", "PDE", "PRE")
KNOWLEDGE = ("AKE", "MKE", "RKE", "KDE", "KRE")
WINDOWED = ("MPE", "RPE", "PDE", "PRE", "MKE", "RKE", "KDE", "KRE")
PAIRED = ("PDE", "PRE", "KDE", "KRE")
#: Each performance index's knowledge index and back (the same statistic on the other error).
COUNTERPART = {**dict(zip(PERFORMANCE, KNOWLEDGE)), **dict(zip(KNOWLEDGE, PERFORMANCE))}
#: Every kind of requirement.
KINDS = PERFORMANCE + KNOWLEDGE + ("settling", "wheel_speed_margin", "momentum_margin", "max_command", "max_torque",
                                   "envelope")
#: Which error component: a body axis (the rotation vector's component), the
#: full rotation angle 4 atan|sigma|, or the half-cone angle about a boresight.
AXES = ("x", "y", "z", "norm", "cone")
INTERPRETATIONS = ("temporal", "ensemble", "mixed")
#: The windows a requirement may be limited to (``mode``): the rows where
#: the controller's law commanded (ctrl_mode NORMAL: not INIT, not SAFE), or
#: where the navigation was not degraded (no FLAG_NAV_DEGRADED: star
#: tracker fixes arriving). "" (the default): every row of the span.
MODES = ("normal", "nav_ok")

#: Unit -> its value in rad.
ANGLE_UNITS = {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "deg": math.pi / 180.0,
               "arcmin": math.pi / 10800.0, "arcsec": math.pi / 648000.0}
#: The bound's units of each kind (unit -> its value in SI); the first is the default when it has one.
UNITS: dict[str, dict[str, float]] = {
    **{k: ANGLE_UNITS for k in PERFORMANCE + KNOWLEDGE + ("settling",)},
    "wheel_speed_margin": {"rad/s": 1.0, "rpm": 2.0 * math.pi / 60.0},
    "momentum_margin": {"N m s": 1.0, "mN m s": 1e-3},
    # either dimension on either wheel kind: the judge converts with Jw (exact, the drive's arithmetic)
    "max_command": {"rad/s^2": 1.0, "N m": 1.0, "mN m": 1e-3},
    "max_torque": {"N m": 1.0, "mN m": 1e-3},
    "envelope": {},
}
#: Kinds whose unit may be left out (their first unit is the default); an
#: angle's unit is always stated (arcsec and rad differ by 2e5).
_DEFAULT_UNIT = ("wheel_speed_margin", "momentum_margin", "max_command", "max_torque")

_POINTING = ("axis", "boresight", "bound", "unit", "confidence", "interpretation", "t_from", "t_to", "phase",
             "settling", "mode")
#: The keys each kind takes (besides name and kind).
KEYS: dict[str, tuple[str, ...]] = {
    **{k: _POINTING for k in ("APE", "AKE")},
    **{k: _POINTING + ("window",) for k in WINDOWED},
    **{k: _POINTING + ("window", "separation") for k in PAIRED},
    "settling": ("axis", "boresight", "bound", "unit", "settle_by", "t_from", "t_to", "phase"),
    "wheel_speed_margin": ("bound", "unit", "t_from", "t_to", "phase", "settling", "mode"),
    "momentum_margin": ("bound", "unit", "t_from", "t_to", "phase", "settling", "mode"),
    "max_command": ("bound", "unit", "t_from", "t_to", "phase", "settling", "mode"),
    "max_torque": ("bound", "unit", "t_from", "t_to", "phase", "settling", "mode"),
    "envelope": (),
}
_ALL_KEYS = ("name", "kind") + tuple(dict.fromkeys(k for keys in KEYS.values() for k in keys))
AFTER_SETTLING = "after_settling"


@dataclass(frozen=True)
class Requirement:
    """One ``[[requirements]]`` row, validated (docs/SCENARIOS.md).

    Attributes
    ----------
    name : str
        Its name, unique in the file.
    kind : str
        One of ``KINDS``.
    axis : str
        One of ``AXES`` for the pointing kinds and settling ("" otherwise).
    boresight : tuple of float or None
        The boresight in the body frame B (axis "cone"), as written.
    bound : float or None
        The bound in ``unit`` (None: envelope).
    unit : str
        The bound's unit ("-" for the envelope: its own normalised bound).
    confidence : float or None
        The probability with which the error must stay within the bound
        (the pointing indices).
    interpretation : str
        "temporal", "ensemble" or "mixed" (the pointing indices; "" otherwise).
    t_from : float or str
        [s] the span's start, or "after_settling".
    t_to : float or None
        [s] the span's end (None: the run's end).
    window : float or None
        [s] the window of MPE, RPE, MKE, RKE, and the two windows of the
        drift and reproducibility indices PDE, PRE, KDE, KRE.
    separation : float or None
        [s] PDE, PRE, KDE, KRE: from one window's start to the start of the
        window it is compared with.
    settle_by : float or None
        [s] settling: the time by which the error must have entered the bound for good.
    settling : str
        With t_from = "after_settling": the settling requirement whose time starts the span.
    mode : str
        One of ``MODES``: only the span's rows in that window are judged ("": all).
    phase : str
        A phase of the guidance (``sc_rt.scenario.tables.guidance.guidance_phases``:
        a slew's "before", "slew", "hold"; a hold's "hold") whose interval
        gave ``t_from`` and ``t_to`` ("": the span as written).
    """

    name: str
    kind: str
    axis: str = ""
    boresight: tuple[float, ...] | None = None
    bound: float | None = None
    unit: str = "-"
    confidence: float | None = None
    interpretation: str = ""
    t_from: float | str = 0.0
    t_to: float | None = None
    window: float | None = None
    separation: float | None = None
    settle_by: float | None = None
    settling: str = ""
    mode: str = ""
    phase: str = ""

    def data(self) -> dict[str, Any]:
        """The row as the TOML data it reads back from (keys left at their
        "not given" value are left out)."""
        out: dict[str, Any] = {"name": self.name, "kind": self.kind}
        for f in dataclasses.fields(self):
            if f.name in ("name", "kind") or f.name not in KEYS[self.kind]:
                continue
            v = getattr(self, f.name)
            if v is None or v == "" or (f.name == "t_from" and v == 0.0 and not isinstance(v, str)):
                continue
            if self.phase and f.name in ("t_from", "t_to"):  # the phase gave them: it reads back as the phase
                continue
            out[f.name] = list(v) if isinstance(v, tuple) else v
        return out


def requirements_data(reqs: tuple[Requirement, ...]) -> list[dict[str, Any]]:
    """The ``[[requirements]]`` rows as TOML data (sc_rt.scenario.keys.scenario_data)."""
    return [r.data() for r in reqs]


def _read_row(t: Table, duration: float | None, phases: dict[str, tuple[float, float | None]]
              ) -> Requirement | None:  # fmt: skip
    name = t.read("name", Spec("str"))
    kind = t.read("kind", Spec("str", choices=KINDS))
    if name is not None and not name.strip():
        t.fail("name", "name must not be empty")
        name = None
    if kind is None:  # its keys cannot be judged: mark them read, report the kind only
        t.used.update(_ALL_KEYS)
        t.finish()
        return None
    allowed = KEYS[kind]
    for key in _ALL_KEYS[2:]:
        if key not in allowed and t.has(key):
            t.used.add(key)
            applies = ", ".join(allowed) if allowed else "none but name and kind"
            t.fail(key, f'{key} does not apply to a kind = "{kind}" requirement (its keys: {applies})')
    v: dict[str, Any] = {}
    ok = name is not None and not any(key not in allowed and t.has(key) for key in _ALL_KEYS[2:])
    if "axis" in allowed:
        v["axis"] = t.read("axis", Spec("str", choices=AXES), default="norm")
        if v["axis"] == "cone":
            b = t.read("boresight", Spec("vector", shape=(3,)),
                       missing='required key is missing (axis = "cone" is the half-cone about this B-frame vector)')
            if b is not None and float(sum(x * x for x in b)) ** 0.5 < 1e-9:
                t.fail("boresight", "boresight must be a non-zero vector")
                b = None
            v["boresight"] = None if b is None else tuple(float(x) for x in b)
            ok = ok and b is not None
        elif t.has("boresight"):
            t.used.add("boresight")
            if v["axis"] is not None:  # a bad axis is reported already
                t.fail("boresight", 'boresight applies to axis = "cone" only')
            ok = False
    if "bound" in allowed:
        v["bound"] = t.read("bound", Spec("number", gt=0))
        unit_spec = Spec("str", choices=tuple(UNITS[kind]))
        if kind in _DEFAULT_UNIT:
            v["unit"] = t.read("unit", unit_spec, default=next(iter(UNITS[kind])))
        else:
            v["unit"] = t.read("unit", unit_spec)
    if "confidence" in allowed:
        v["confidence"] = t.read("confidence", Spec("number", gt=0, le=1))
        v["interpretation"] = t.read("interpretation", Spec("str", choices=INTERPRETATIONS), default="temporal")
    if "window" in allowed:
        v["window"] = t.read("window", Spec("number", gt=0))
    if "separation" in allowed:
        v["separation"] = t.read("separation", Spec("number", gt=0))
    if "settle_by" in allowed:
        v["settle_by"] = t.read("settle_by", Spec("number", gt=0))
    if "t_from" in allowed:
        v.update(_read_span(t, kind, duration, phases))
        ok = ok and v.pop("span_ok")
    if "mode" in allowed:
        v["mode"] = t.read("mode", Spec("str", choices=MODES), default="")
    t.finish()
    if not ok or any(x is None for k, x in v.items() if k not in ("t_to", "boresight")):
        return None
    return Requirement(name=name, kind=kind, **v)


def _read_phase(t: Table, duration: float | None, phases: dict[str, tuple[float, float | None]]
                ) -> dict[str, Any]:  # fmt: skip
    """``phase``: the span of a named phase of the guidance (t_from, t_to)."""
    name = t.read("phase", Spec("str"))
    out: dict[str, Any] = {"t_from": None, "t_to": None, "settling": "", "phase": name or "", "span_ok": False}
    for key in ("t_from", "t_to", "settling"):
        if t.has(key):
            t.used.add(key)
            t.fail(key, f"{key} and phase both give the span: give one of them")
            return out
    if name is None:
        return out
    if name not in phases:
        have = ", ".join(f'"{p}"' for p in phases) or "none (the paper's or a file's reference has no phases)"
        t.fail("phase", f"phase {format_value(name)} is not a phase of this scenario's [guidance] (its phases: {have})")
        return out
    start, stop = phases[name]
    if duration is not None and start >= duration:
        t.fail("phase", f"phase {format_value(name)} starts at {start:g} s, at or after run.duration = {duration:g} s")
        return out
    stop = None if stop is None or (duration is not None and stop >= duration) else stop
    if stop is not None and stop <= start:
        t.fail("phase", f"phase {format_value(name)} is empty ({start:g} s to {stop:g} s)")
        return out
    out.update(t_from=float(start), t_to=None if stop is None else float(stop), span_ok=True)
    return out


def _read_span(t: Table, kind: str, duration: float | None,
               phases: dict[str, tuple[float, float | None]] | None = None) -> dict[str, Any]:
    """t_from (a number or "after_settling"), t_to, and the settling row named;
    or ``phase``, a phase of the guidance (``phases``: name -> [start, end) s)."""
    if t.has("phase"):
        return _read_phase(t, duration, phases or {})
    ok = True
    raw_from = t.raw("t_from")
    if isinstance(raw_from, str) and kind != "settling":
        t.used.add("t_from")
        t_from: Any = raw_from
        if raw_from != AFTER_SETTLING:
            t.fail("t_from", f't_from must be a number >= 0 [s] or "{AFTER_SETTLING}"')
            ok = False
    else:
        t_from = t.read("t_from", Spec("number", ge=0), default=0.0)
        ok = t_from is not None
    t_to = t.read("t_to", Spec("number", gt=0), default=None)
    if t.has("t_to") and t_to is None:
        ok = False
    settling = ""
    if "settling" in KEYS[kind]:
        settling = t.read("settling", Spec("str"), default="")
        if settling is None:
            ok, settling = False, ""
        elif settling and t_from != AFTER_SETTLING:
            t.fail("settling", f'settling names the span\'s start: give it with t_from = "{AFTER_SETTLING}"')
            ok = False
    if ok and isinstance(t_from, float) and t_to is not None and t_to <= t_from:
        t.fail("t_to", f"t_to must be > t_from = {t_from:g} s")
        ok = False
    if ok and duration is not None:
        if isinstance(t_from, float) and t_from >= duration:
            t.fail("t_from", f"t_from must be < run.duration = {duration:g} s")
            ok = False
        if t_to is not None and t_to > duration + 1e-9:
            t.fail("t_to", f"t_to must be <= run.duration = {duration:g} s")
            ok = False
    return {"t_from": t_from, "t_to": t_to, "settling": settling, "span_ok": ok}


def read_requirements(root: Table, duration: float | None,
                      phases: dict[str, tuple[float, float | None]] | None = None
                      ) -> tuple[Requirement, ...] | None:  # fmt: skip
    """The ``[[requirements]]`` rows of the file (``()`` without any), or
    None after reporting their problems on ``root.doc``. ``duration``: the
    run's [s] (None when [run] is broken), the spans must lie within it;
    ``phases``: the guidance's named phases (a row's ``phase``)."""
    root.used.add("requirements")
    if not root.has("requirements"):
        return ()
    raw = root.raw("requirements")
    if not (isinstance(raw, list) and all(isinstance(r, dict) for r in raw)):
        root.fail("requirements", "requirements must be an array of tables ([[requirements]])")
        return None
    rows: list[Requirement | None] = []
    tables = []
    for i, entry in enumerate(raw):
        t = Table(root.doc, f"requirements[{i}]", entry)
        tables.append(t)
        rows.append(_read_row(t, duration, phases or {}))
    first: dict[str, int] = {}
    for i, (t, r) in enumerate(zip(tables, rows)):
        if r is None:
            continue
        if r.name in first:
            t.fail("name", f"name {format_value(r.name)} is taken by requirements[{first[r.name]}]: "
                           "each requirement has its own name")
            rows[i] = None
        else:
            first[r.name] = i
    if any(r is None for r in rows):  # the cross-references are judged on a file that read well
        return None
    settlers = {r.name: r for r in rows if r is not None and r.kind == "settling"}
    for i, (t, r) in enumerate(zip(tables, rows)):
        if r is None or r.t_from != AFTER_SETTLING:
            continue
        if r.settling:
            if r.settling not in settlers:
                kinds = {x.name: x.kind for x in rows if x is not None}
                why = (f'is a kind = "{kinds[r.settling]}" requirement' if r.settling in kinds
                       else "names no requirement of this file")
                t.fail("settling", f'settling = {format_value(r.settling)} {why}: name a kind = "settling" one')
                rows[i] = None
        elif len(settlers) == 1:
            rows[i] = dataclasses.replace(r, settling=next(iter(settlers)))
        else:
            how = ("add a [[requirements]] row of kind = \"settling\"" if not settlers else
                   "name one with settling = " + " or ".join(format_value(n) for n in settlers))
            t.fail("t_from", f'"{AFTER_SETTLING}" needs the settling requirement that starts the span: {how}')
            rows[i] = None
    if any(r is None for r in rows):
        return None
    return tuple(r for r in rows if r is not None)
