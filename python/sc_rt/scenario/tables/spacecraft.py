"""The spacecraft's and the faults' tables of a scenario file: ``[spacecraft]``
(or ``[spacecraft.capture]``, the combined spacecraft), ``[disturbance]`` and
``[[faults]]``, each value checked as read (sc_rt.scenario.reader reads the
rest)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from sc_rt._core import mrp_to_dcm
from sc_rt.model.actuators import ActuatorParams, WheelFault
from sc_rt.model.combined import RigidBody, combine
from sc_rt.model.plant_params import DisturbanceParams, PlantParams
from sc_rt.scenario.schema import Spec, Table, build, format_value, read_only
from sc_rt.scenario.tables.wheels import check_wheel_fault

__all__ = ["read_spacecraft", "read_faults"]

_FAULT = WheelFault(wheel=0)  # defaults of a fault's optional keys

_MAT33 = Spec("matrix", shape=(3, 3))
_MAT34 = Spec("matrix", shape=(3, 4))
_WHEELS = Spec("vector", shape=(4,), scalar_ok=True)
_V3 = Spec("vector", shape=(3,))


def _inertia_problem(J: np.ndarray) -> str:
    """Why J is not a rigid body's inertia matrix ("" if it is one)."""
    if np.abs(J - J.T).max() > 1e-9 * np.abs(J).max():
        return "must be symmetric"
    moments = np.linalg.eigvalsh(J)
    if moments[0] <= 0:
        return f"must be positive definite (eigenvalues {format_value(np.round(moments, 6))})"
    if moments[0] + moments[1] < moments[2] * (1 - 1e-9):
        return (
            f"is not a rigid body's inertia: principal moments {format_value(np.round(moments, 6))} "
            "break the triangle inequality I1 + I2 >= I3"
        )
    return ""


def _wheel_axes_problem(C: np.ndarray) -> str:
    """Why C cannot be a wheel matrix ("" if it can); the checks of C++ validate()."""
    norms = np.linalg.norm(C, axis=0)
    if np.any(np.abs(norms - 1.0) > 1e-2):
        return f"columns must be unit spin axes (norms {format_value(np.round(norms, 4))})"
    sv = np.linalg.svd(C, compute_uv=False)
    if sv[2] < 1e-6 * sv[0]:
        return "is rank-deficient: the wheels cannot produce torque about every axis"
    return ""


def _read_checked(t: Table, name: str, spec: Spec, problem_of: Any, missing: str = "") -> Any:
    """A required value that must also pass ``problem_of`` (returns "" when fine)."""
    value = t.read(name, spec, missing=missing)
    if value is not None and (problem := problem_of(value)):
        t.fail(name, f"{name} {problem}")
        return None
    return value


def _read_capture(t: Table) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(J0, Cbar) of the combined spacecraft from [spacecraft.capture]."""
    frame = t.read("frame", Spec("str", choices=("service", "principal")), default="service")
    s, g = t.sub("service"), t.sub("target")
    mass = Spec("number", gt=0)
    service = (
        s.read("mass", mass),
        _read_checked(s, "inertia", _MAT33, _inertia_problem),
        _read_checked(s, "C", _MAT34, _wheel_axes_problem),
    )
    target = (
        g.read("mass", mass),
        _read_checked(g, "inertia", _MAT33, _inertia_problem),
        g.read("position", Spec("vector", shape=(3,))),
        g.read("attitude", Spec("vector", shape=(3,), mrp=True)),
    )
    for sub in (s, g, t):
        sub.finish()
    if any(v is None for v in (frame, *service, *target)):
        return None, None
    c = combine(
        RigidBody(service[0], service[1]), service[2],
        RigidBody(target[0], target[1]), target[2], mrp_to_dcm(target[3]), frame,
    )  # fmt: skip
    return read_only(c.J_C), read_only(c.Cbar)


def read_spacecraft(t: Table, dist: Table) -> tuple[PlantParams | None, ActuatorParams | None]:
    if t.has("capture"):
        for name in ("J0", "Cbar"):
            if t.has(name):
                t.fail(name, f"give either {name} or [{t.key}.capture], not both")
            t.used.add(name)
        J0, Cbar = _read_capture(t.sub("capture"))
    else:
        either = f"required key is missing (or give a [{t.key}.capture] table)"
        J0 = _read_checked(t, "J0", _MAT33, _inertia_problem, either)
        Cbar = _read_checked(t, "Cbar", _MAT34, _wheel_axes_problem, either)
    dJ = t.read("dJ", _MAT33)
    if dJ is not None and np.abs(dJ - dJ.T).max() > 1e-9 * max(np.abs(dJ).max(), 1.0):
        t.fail("dJ", "dJ must be symmetric")
        dJ = None
    if J0 is not None and dJ is not None and (problem := _inertia_problem(J0 + dJ)):
        t.fail("dJ", f"the true inertia J0 + dJ = {format_value(J0 + dJ)} {problem}")
        dJ = None
    Jw = t.read("Jw", dataclasses.replace(_WHEELS, gt=0))
    umin, umax = t.read("umin", _WHEELS), t.read("umax", _WHEELS)
    if umin is not None and umax is not None and np.any(umin >= umax):
        bad = ", ".join(str(i + 1) for i in np.flatnonzero(umin >= umax))
        t.fail("umin", f"umin must be < umax = {format_value(t.raw('umax'))} for every wheel "
                       f"(not for wheel {bad})")  # fmt: skip
        umin = None
    w0 = t.read("w0", Spec("number", ge=0))
    max_speed = t.read(
        "max_wheel_speed",
        dataclasses.replace(_WHEELS, gt=0, allow_inf=True),
        default=read_only(np.full(4, np.inf)),
    )
    t.finish()
    amp, freq = dist.read("amp", _V3), dist.read("freq", dataclasses.replace(_V3, ge=0))
    bias = dist.read("bias", _V3, default=read_only(np.zeros(3)))
    dist.finish()
    disturbance = build(dist, DisturbanceParams, amp=amp, freq=freq, bias=bias)
    plant = build(t, PlantParams, J0=J0, dJ=dJ, Cbar=Cbar, Jw=Jw, w0=w0, disturbance=disturbance)
    actuators = build(t, ActuatorParams, umin=umin, umax=umax, max_wheel_speed=max_speed)
    return plant, actuators


def read_faults(root: Table, plant_step: float | None) -> tuple[WheelFault, ...] | None:
    root.used.add("faults")
    raw = root.raw("faults") if root.has("faults") else []
    if not (isinstance(raw, list) and all(isinstance(f, dict) for f in raw)):
        root.fail("faults", "faults must be an array of tables ([[faults]])")
        return None
    faults, first_of_wheel = [], {}
    for i, entry in enumerate(raw):
        t = Table(root.doc, f"faults[{i}]", entry)
        wheel = t.read("wheel", Spec("int", ge=1, le=4))
        eff = t.read("effectiveness", Spec("number", ge=0, le=1), default=_FAULT.effectiveness)
        bias = t.read("bias", Spec("number"), default=_FAULT.bias)
        onset = t.read("onset", Spec("number", ge=0))
        end = t.read("end", Spec("number"), default=_FAULT.end)
        rate = t.read("rate", Spec("number", gt=0), default=_FAULT.rate)
        stuck = t.read("stuck", Spec("bool"), default=_FAULT.stuck)
        friction = t.read("friction", Spec("number", ge=0), default=_FAULT.friction)
        t.finish()
        check_wheel_fault(t, bool(stuck), rate, root.has("wheels"), plant_step)
        if wheel is not None and wheel in first_of_wheel:
            t.fail("wheel", f"wheel {wheel} already has a fault (faults[{first_of_wheel[wheel]}]): "
                   "one fault per wheel")  # fmt: skip
            wheel = None
        elif wheel is not None:
            first_of_wheel[wheel] = i
        if end is not None and onset is not None and end <= onset:
            t.fail("end", f"end must be > onset ({onset:g} s)")
            onset = None
        if stuck and (t.has("effectiveness") or t.has("bias") or t.has("friction")):
            t.fail("stuck", "a stuck wheel ignores effectiveness, bias and friction: give stuck or those")
            stuck = None
        if t.has("end") and end is None:  # end was given but is bad (reported)
            continue
        fault = build(
            t, WheelFault, ("end",), wheel=None if wheel is None else wheel - 1,
            effectiveness=eff, bias=bias, onset=onset, end=end, rate=rate, stuck=stuck, friction=friction,
        )  # fmt: skip
        if fault is not None:
            faults.append(fault)
    return tuple(faults) if len(faults) == len(raw) else None
