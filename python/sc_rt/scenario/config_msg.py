"""A scenario's controller part as the controller receives it (docs/HIL.md):
the LCM ``controller_config_t`` (:func:`controller_config_msg`), every field
filled from the typed scenario (sc_rt.scenario.model), and the C++ config
decoded from its bytes by the same translator as the real-time process
(:func:`core_config`), the magnetic part included (:func:`fill_magnetic`).
``Scenario.controller_config_msg`` and
``Scenario.core_config`` call these.
"""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path
from typing import Any

import numpy as np
from sc_rt_lcm import controller_config_t

from sc_rt import _core
from sc_rt.pylaw import registry_spec
from sc_rt.scenario.tables.laws import law_table_name
from sc_rt.scenario.lawspec import law_problem, law_spec
from sc_rt.scenario.schema import convert, field_spec
from sc_rt.scenario.tables.sensors import nav_config

__all__ = ["controller_config_msg", "fill_nav", "fill_magnetic", "core_config"]


def controller_config_msg(
    scn: Any, law: str | None = None, control_rate_hz: float | None = None, *, nav: bool = True
) -> controller_config_t:
    """The controller's part of the scenario as an LCM message, every field filled.

    ``law`` and ``control_rate_hz`` override the run's values; ``nav``
    False leaves the estimator's part out (the offline engines build it
    from the scenario). ValueError for what the message cannot carry: an
    initial gyro calibration estimate (``[controller.estimator]
    initial_scale_factor``, ``initial_misalignment``; offline engines only).
    """
    # a law given here in any form (file.py:Class without python:) as the reader writes a file's
    law = scn.run.controller if law is None else law_spec(law, Path.cwd()) if isinstance(law, str) else law
    rate = scn.run.control_rate_hz if control_rate_hz is None else control_rate_hz
    for name, value in (("controller", law), ("control_rate_hz", rate)):
        _, problem = convert(value, field_spec(type(scn.run), name))
        if problem:
            raise ValueError(f"{name} {problem}, got {value!r}")
    if problem := law_problem(law):  # the form a scenario holds (sc_rt.scenario.lawspec.law_spec)
        raise ValueError(f"controller {problem}, got {law!r}")
    p, a, g, c = scn.plant, scn.actuators, scn.guidance, scn.controller
    m = controller_config_t()
    m.utime = time.time_ns() // 1000
    m.scenario = scn.name
    m.law = law
    m.law_api_version = _core.LAW_API_VERSION
    # its table by the law's name; [controller.params] of a plugin or Python law the file
    # runs is kept under the spec (the reader loads no law to learn its name)
    table = c.table(law_table_name(law)) or c.table(law)
    m.n_law_params = len(table)
    m.law_param_keys = [k for k, _ in table]
    m.law_param_len = [len(v) for _, v in table]
    m.law_param_values = [float(x) for _, v in table for x in v]
    m.n_law_param_values = len(m.law_param_values)
    m.control_rate_hz = float(rate)
    m.J0 = p.J0.tolist()
    m.Cbar = p.Cbar.tolist()
    m.Jw = p.Jw.tolist()
    m.umin = a.umin.tolist()
    m.umax = a.umax.tolist()
    m.wheel_torque_command = a.wheels is not None and a.wheels.command == "torque"
    # the wheels' speed limits, 0 for none (finite on the wire; the core reads 0 as inf)
    m.wheel_speed_max = ([max(float(w.omega_max), 0.0) for w in a.wheels.limits] if a.wheels is not None
                         else [float(v) if np.isfinite(v) else 0.0 for v in a.max_wheel_speed])
    m.w0 = float(p.w0)
    g.fill_config(m)
    # The wire names are the field names with a prefix (safety: none).
    for prefix, group in (("ppc_", c.ppc), ("", c.safety)):
        for f in dataclasses.fields(group):
            value = getattr(group, f.name)
            wire = value.tolist() if isinstance(value, np.ndarray) else value
            setattr(m, prefix + f.name, wire)
    m.pinv_damping = float(c.pinv_damping)
    if nav:
        fill_nav(scn, m)
    fill_magnetic(scn, m)
    return m


def fill_magnetic(scn: Any, m: controller_config_t) -> None:
    """The controller's magnetic part (``mag_*``, ``bdot_*``; a scenario with
    ``[momentum]`` or ``[bdot]``, else all off and zeros): the core's
    ``MagneticConfig`` the scenario builds (``MagneticControl.to_core``: the
    nominal rods' axes G_B [-] and limits [A m^2], the manager's and
    B-dot's parameters), field by field; the controller decodes it back
    (cpp/shell/translate.cpp ``magnetic_from_lcm``), so the offline engines
    and the controller process run the same configuration."""
    m.mag_G_B = [[0.0] * 6 for _ in range(3)]
    m.mag_dipole_max = [0.0] * 6
    if scn.magnetic_control is None:
        return
    mc = scn.magnetic_control.to_core(scn.plant.magnetorquers)
    G = np.asarray(mc.rods.G_B, float)
    n = G.shape[1]
    m.mag_rods_enabled = True
    m.mag_n_rods = n
    m.mag_G_B = [[float(G[i, j]) if j < n else 0.0 for j in range(6)] for i in range(3)]
    m.mag_dipole_max = [float(v) for v in mc.rods.dipole_max] + [0.0] * (6 - n)
    p, b = mc.momentum, mc.bdot
    m.mag_momentum_enabled = bool(mc.momentum_enabled)
    m.mag_unload_kind = int(p.kind)
    for name in ("gain", "on_fraction", "off_fraction", "capacity", "null_gain", "null_bias"):
        setattr(m, "mag_" + name, float(getattr(p, name)))
    m.mag_hysteresis = bool(p.hysteresis)
    m.bdot_enabled = bool(mc.bdot_enabled)
    m.bdot_normalized = bool(b.normalized)
    m.bdot_derivative = int(b.derivative)
    for name in ("gain", "filter_tau", "rate_on", "rate_off"):
        setattr(m, "bdot_" + name, float(getattr(b, name)))


def fill_nav(scn: Any, m: controller_config_t) -> None:
    """The estimator's part of the controller's configuration (a scenario
    with [sensors]; else nav_enabled 0 and zeros): the MEKF's noise model
    and the run's initial estimate, computed here from the seed as the
    offline loop does (``_core.initial_estimate``)."""
    if scn.sensors is None:
        return
    e = scn.sensors.estimator
    if np.any(np.asarray(e.initial_scale_factor) != 0.0) or np.any(np.asarray(e.initial_misalignment) != 0.0):
        raise ValueError("[controller.estimator] initial_scale_factor / initial_misalignment: controller_config_t "
                         "does not carry an initial calibration estimate; run it with sc-rt sim")
    nav = nav_config(scn.sensors, scn.run.plant_step, f"{scn.path}")
    k = nav.mekf
    m.nav_enabled = True
    m.nav_use_estimate = bool(nav.use_estimate)
    for name in ("arw", "rrw", "bias_sigma", "bias_tau", "quantization", "sigma_cross",
                 "sigma_boresight", "initial_attitude_sigma", "initial_bias_sigma", "degraded_after",
                 "initial_scale_factor_sigma", "initial_misalignment_sigma"):
        setattr(m, "nav_" + name, float(getattr(k, name)))
    m.nav_boresight = [float(v) for v in k.boresight]
    m.nav_history = int(k.history)
    m.nav_calibrate = bool(k.calibrate)
    sigma0 = _core.initial_estimate(nav.sensors.seed, k.initial_attitude_sigma,
                                    np.asarray(scn.initial.sigma_BN, float))
    m.nav_sigma0 = [float(v) for v in sigma0]
    # [sensors.magnetometer]: the controller rotates its samples to B with the known mounting
    mag = nav.sensors.magnetometer
    m.nav_mag_enabled = bool(mag.enabled)
    m.nav_mag_R_SB = [[float(v) for v in row] for row in np.asarray(mag.R_SB if mag.enabled else np.eye(3))]


def core_config(
    scn: Any, law: str | None = None, control_rate_hz: float | None = None
) -> _core.ControllerConfig:
    """The C++ config, decoded from the LCM bytes as the real-time process
    does. A Python law is put in the core's registry first (sc_rt.pylaw),
    so that a controller built from the config in this process runs it."""
    msg = controller_config_msg(scn, law, control_rate_hz, nav=False)  # the core reads no nav_* field
    msg.law = registry_spec(msg.law)  # a Python law: into the core's registry (sc_rt.pylaw)
    return _core.ControllerConfig.from_lcm_bytes(msg.encode())  # the magnetic part too (fill_magnetic)
