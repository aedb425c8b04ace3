"""The controller's time contract (issue #42, item 1; docs/CORE.md, "The
time contract"): every step costs bounded work whatever its time stamp, a
law never sees a dt beyond MAX_DT_PERIODS periods, and a stamp that jumps
ahead beyond that or goes back puts the controller SAFE with FLAG_TIME_JUMP,
counted, then re-engages. The work is counted (the guidance's RK4 steps,
the law's calls), never timed. The reference far from the controller's time
line is checked against an independent evaluation of its definition
(sigma_DN_dot = G(sigma_DN) omega_DN_D(t) from sigma_d0 at t = 0): a
quaternion RK4 in numpy, its per-step transitions multiplied together.

    .venv/bin/python tests/test_time_contract.py   # the table of work counts
"""

from __future__ import annotations

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.pylaw import register
from sc_rt.scenario.reader import load_scenario

from conftest import core_config

SCENARIO = "ppc_feasible_1khz"
DAY = 86400.0
#: law calls of one engaged step (step, after) and of a (re-)engaging one (reset too)
STEP_CALLS, ENGAGE_CALLS = 2, 3
#: RK4 steps of the guidance over one period: one, or two where the stamps'
#: rounding at large t makes the span a hair (> 1e-9 relative) longer than
#: the period (t = 1 day at 1 kHz: its ulp is 1.5e-8 of the period)
PERIOD_STEPS = 2


def _setup():
    scn = load_scenario(SCENARIO)
    x = np.concatenate([scn.initial.sigma_BN, scn.initial.omega_BN_B, scn.initial.wheel_speed])
    return scn.core_config(), x


CFG, X0 = _setup()
T = 1.0 / CFG.control_rate_hz


def meas(t: float, ok: bool = True) -> _core.Measurement:
    s = X0[0:3] if ok else np.full(3, np.nan)
    return _core.Measurement(t, s, X0[3:6], X0[6:10])


def controller(prepared: bool = True) -> _core.Controller:
    ctl = _core.Controller(CFG)
    if prepared:
        ctl.prepare()
    return ctl


def work(ctl) -> tuple[int, int]:
    """(guidance RK4 steps, law calls) so far."""
    return ctl.guidance.rk4_steps, ctl.counts.law_calls


def step_work(ctl, m):
    """One step and its work: (command, RK4 steps, law calls)."""
    r0, l0 = work(ctl)
    cmd = ctl.step(m)
    r1, l1 = work(ctl)
    return cmd, r1 - r0, l1 - l0


def rk4_bound(ctl) -> int:
    """The most RK4 steps one step may take once the period table is built:
    the time line's catch-up or the evaluation from the nearest anchor."""
    return max(_core.GUIDANCE_MAX_CATCH_UP, ctl.guidance.period_table.stride + 1)


# --------------------------------------------------------------------------- #
# The independent evaluation of the paper's reference.


def _omega_matrices(p, t: np.ndarray) -> np.ndarray:
    """(N, 4, 4) Omega with q_dot = Omega q for the quaternion q = (x, y, z, w)
    of R_DN and the rate omega_DN_D(t) in D (body rates)."""
    w = (np.asarray(p.omega_bias) + np.outer(np.cos(p.omega_freq * t), p.omega_cos)
         + np.outer(np.sin(p.omega_freq * t), p.omega_sin))  # fmt: skip
    wx, wy, wz = w[:, 0], w[:, 1], w[:, 2]
    o = np.zeros((len(t), 4, 4))
    o[:, 0, 1], o[:, 0, 2], o[:, 0, 3] = wz, -wy, wx
    o[:, 1, 0], o[:, 1, 2], o[:, 1, 3] = -wz, wx, wy
    o[:, 2, 0], o[:, 2, 1], o[:, 2, 3] = wy, -wx, wz
    o[:, 3, 0], o[:, 3, 1], o[:, 3, 2] = -wx, -wy, -wz
    return 0.5 * o


def reference_sigma(p, t_end: float, h: float = 0.25) -> np.ndarray:
    """sigma_DN(t_end) of the paper's kind from sigma_d0 at t = 0 (or back to
    t_end < 0): classical RK4 on the quaternion, whose kinematics are linear,
    so each step is a 4x4 matrix; their product is taken pairwise."""
    n = max(1, int(np.ceil(abs(t_end) / h)))
    h = t_end / n
    t = np.arange(n) * h
    a0, am, a1 = _omega_matrices(p, t), _omega_matrices(p, t + h / 2), _omega_matrices(p, t + h)
    eye = np.eye(4)
    k1 = a0
    k2 = am @ (eye + h / 2 * k1)
    k3 = am @ (eye + h / 2 * k2)
    k4 = a1 @ (eye + h * k3)
    phi = eye + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    while len(phi) > 1:  # later steps on the left
        if len(phi) % 2:
            phi = np.concatenate([phi, eye[None]])
        phi = phi[1::2] @ phi[0::2]
    s0 = np.asarray(p.sigma_d0, float)
    q = phi[0] @ np.r_[2 * s0, 1 - s0 @ s0] / (1 + s0 @ s0)
    q /= np.linalg.norm(q)
    if q[3] < 0:
        q = -q
    return q[:3] / (1 + q[3])


def assert_reference(sigma, p, t: float):
    """sigma equals the independent evaluation at t: 1e-9 up to 1000 s (h =
    0.25 s: 3e-12 at 600 s), 1e-7 beyond (h = 0.5 s: 9e-9 after a day)."""
    far = abs(t) > 1000.0
    exp = reference_sigma(p, t, h=0.5 if far else 0.25)
    np.testing.assert_allclose(np.asarray(sigma), exp, rtol=0, atol=1e-7 if far else 1e-9)


# --------------------------------------------------------------------------- #
# A gap, a late joiner, a jump ahead, a step back.


@pytest.mark.parametrize("gap", [1.0, 10.0, 600.0, DAY])
def test_reengaging_after_a_gap_costs_bounded_work(gap):
    """Engaged at 1 kHz, one invalid state (SAFE), then a state `gap` later:
    the re-engagement costs at most the bound's RK4 steps and three law
    calls (on main: 1,001 / 10,001 / 600,001 / 86.4 M RK4 steps), and its
    reference is the definition's at the new time."""
    ctl = controller()
    for k in range(10):
        ctl.step(meas(k * T))
    assert ctl.step(meas(10 * T, ok=False)).mode == _core.MODE_SAFE
    t = 10 * T + gap
    cmd, rk4, calls = step_work(ctl, meas(t))
    assert rk4 <= rk4_bound(ctl), rk4
    assert calls == ENGAGE_CALLS and cmd.mode == _core.MODE_NORMAL and ctl.t0 == t
    assert ctl.counts.engagements == 2 and ctl.counts.time_jumps == 0
    assert_reference(cmd.sigma_DN, CFG.guidance, t)
    for k in range(1, 11):  # then one RK4 step per period (see PERIOD_STEPS) and two law calls
        cmd, rk4, calls = step_work(ctl, meas(t + k * T))
        assert rk4 <= PERIOD_STEPS and (calls, cmd.mode) == (STEP_CALLS, _core.MODE_NORMAL)


@pytest.mark.parametrize("t0", [DAY, 10 * DAY])
def test_a_late_joiner_costs_bounded_work(t0):
    """A controller whose first state is at t0 engages there with bounded
    work: prepared (as the controller processes do), the bound; unprepared,
    the period table once (a property of the reference, not of t0) plus the
    bound. On main: t0 / T RK4 steps (86.4 M for a day at 1 kHz)."""
    for prepared in (True, False):
        ctl = controller(prepared)
        cmd, rk4, calls = step_work(ctl, meas(t0))
        table = ctl.guidance.period_table
        once = 0 if prepared else table.n_steps
        assert table.kind == "periodic" and 0 < table.n_steps <= _core.GUIDANCE_PERIOD_STEPS_MAX
        assert once < rk4 <= once + rk4_bound(ctl), (prepared, rk4)
        assert calls == ENGAGE_CALLS and cmd.mode == _core.MODE_NORMAL and ctl.t0 == t0
        cmd, rk4, calls = step_work(ctl, meas(t0 + T))
        assert rk4 <= PERIOD_STEPS and (calls, cmd.mode) == (STEP_CALLS, _core.MODE_NORMAL)
    if t0 == DAY:
        assert_reference(ctl.step(meas(t0 + 2 * T)).sigma_DN, CFG.guidance, t0 + 2 * T)


def _normal_run(ctl, t_from: float, n: int) -> list:
    return [ctl.step(meas(t_from + k * T)) for k in range(n)]


def test_a_state_stamped_1000_s_ahead_is_a_safe_time_jump_then_reengages_bounded():
    """On main the controller integrated 1,000,000 RK4 steps in that step,
    stayed NORMAL and its observer diverged (z1 ~ -7.5e7). Now: SAFE zeros
    with FLAG_TIME_JUMP, counted, no law call, bounded work; the next state
    re-engages, and the observer then is the one of a controller engaged
    there afresh: finite, bounded."""
    ctl = controller()
    _normal_run(ctl, 0.0, 200)
    t_jump = 199 * T + 1000.0
    cmd, rk4, calls = step_work(ctl, meas(t_jump))
    assert cmd.mode == _core.MODE_SAFE and cmd.flags & _core.FLAG_TIME_JUMP
    assert not cmd.flags & _core.FLAG_TIME_NOT_ADVANCING
    assert not np.any(cmd.u_cmd) and not np.any(cmd.u_sat)
    assert (ctl.counts.jumps_ahead, ctl.counts.steps_back) == (1, 0)
    assert calls == 0 and rk4 <= rk4_bound(ctl)
    assert_reference(cmd.sigma_DN, CFG.guidance, t_jump)  # the telemetry is true at the new time
    after = _normal_run(ctl, t_jump + T, 2000)
    assert ctl.counts.engagements == 2 and ctl.t0 == t_jump + T
    assert all(c.mode == _core.MODE_NORMAL for c in after)
    assert not any(c.flags & (_core.FLAG_TIME_JUMP | _core.FLAG_TIME_NOT_ADVANCING) for c in after)
    fresh = controller()
    ref = _normal_run(fresh, t_jump + T, 2000)
    z = np.array([np.r_[c.z1, c.z2] for c in after])
    assert np.all(np.isfinite(z)) and np.abs(z).max() < 1.0, np.abs(z).max()
    np.testing.assert_allclose(z, [np.r_[c.z1, c.z2] for c in ref], rtol=0, atol=1e-9)
    np.testing.assert_allclose([c.u_cmd for c in after], [c.u_cmd for c in ref], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("back_to", [0.1, 100.0])
def test_a_state_stamped_back_is_a_safe_time_jump_then_reengages(back_to):
    """On main a state stamped before the previous one left the controller
    NORMAL with FLAG_TIME_NOT_ADVANCING on every later step (its time line
    stayed ahead). Now: SAFE with FLAG_TIME_JUMP (and
    FLAG_TIME_NOT_ADVANCING), counted, bounded work even a day back; the
    next state re-engages at its own time and the steps go on unflagged."""
    ctl = controller()
    t_last = 0.2 if back_to < 0.2 else DAY
    _normal_run(ctl, t_last - 20 * T, 21)
    cmd, rk4, calls = step_work(ctl, meas(back_to))
    assert cmd.mode == _core.MODE_SAFE
    assert cmd.flags & _core.FLAG_TIME_JUMP and cmd.flags & _core.FLAG_TIME_NOT_ADVANCING
    assert (ctl.counts.jumps_ahead, ctl.counts.steps_back) == (0, 1)
    assert calls == 0 and rk4 <= rk4_bound(ctl)
    assert_reference(cmd.sigma_DN, CFG.guidance, back_to)
    after = _normal_run(ctl, back_to + T, 50)
    assert ctl.counts.engagements == 2 and ctl.t0 == back_to + T
    assert all(c.mode == _core.MODE_NORMAL and c.flags & 0b11_1000_0000 == 0 for c in after)


def test_dt_up_to_the_cap_continues_beyond_it_is_a_jump():
    """dt = MAX_DT_PERIODS periods is a step (the law keeps its states);
    a hair more is a jump. At 10 Hz the cap is 1 s."""
    cfg = core_config("dsc-ppc", 10.0)
    ctl = _core.Controller(cfg)
    assert ctl.max_dt == _core.MAX_DT_PERIODS / 10.0 == 1.0
    m = lambda t: _core.Measurement(t, X0[0:3], X0[3:6], X0[6:10])  # noqa: E731
    ctl.step(m(0.5))
    assert ctl.step(m(1.5)).mode == _core.MODE_NORMAL and ctl.counts.engagements == 1
    jump = ctl.step(m(np.nextafter(2.5, 3.0)))
    assert jump.mode == _core.MODE_SAFE and jump.flags & _core.FLAG_TIME_JUMP
    assert ctl.counts.jumps_ahead == 1


class _Recorder:
    """A Python law that records the dt of every call and commands zero."""

    dts: list = []

    def __init__(self, setup):
        pass

    def reset(self, inp):
        _Recorder.dts.append(("reset", inp.dt))

    def step(self, inp):
        _Recorder.dts.append(("step", inp.dt))
        return np.zeros(4), {}


def test_the_law_never_sees_a_dt_beyond_the_cap_and_every_step_is_bounded():
    """Stamps of every kind (periods with jitter, the cap exactly, gaps of
    a second to a day, repeats, steps back, invalid states): the law's dt
    stays within [0, max_dt], each step costs the bound at most, and the
    counted jumps are the flagged steps."""
    cfg = core_config("pd", 10.0)
    cfg.law = register(_Recorder)
    ctl = _core.Controller(cfg)
    ctl.prepare()
    _Recorder.dts = []
    rng = np.random.default_rng(42)
    kinds = [0.1, 0.1, 0.1, 0.07, 0.13, 1.0, 0.0, 1.5, 60.0, DAY, -0.05, -3600.0, "nan"]
    t, flagged = 1000.0, 0
    for _ in range(400):
        d = kinds[rng.integers(len(kinds))]
        ok = d != "nan"
        t = t + (float(d) if ok else 0.1)
        cmd, rk4, calls = step_work(ctl, _core.Measurement(t, X0[0:3] if ok else np.full(3, np.nan), X0[3:6],
                                                            X0[6:10]))
        assert rk4 <= rk4_bound(ctl) and calls <= ENGAGE_CALLS, (t, rk4, calls)
        flagged += bool(cmd.flags & _core.FLAG_TIME_JUMP)
        assert bool(cmd.flags & _core.FLAG_TIME_JUMP) <= (cmd.mode == _core.MODE_SAFE)
    dts = np.array([dt for _, dt in _Recorder.dts])
    assert len(dts) > 200 and dts.min() >= 0.0 and dts.max() <= ctl.max_dt
    assert dts.max() == pytest.approx(ctl.max_dt)  # the cap itself was reached
    assert all(dt == 0.0 for call, dt in _Recorder.dts if call == "reset")
    assert flagged == ctl.counts.time_jumps > 10 and ctl.counts.jumps_ahead > 0 and ctl.counts.steps_back > 0


# --------------------------------------------------------------------------- #
# The reference from its definition, in bounded work.


@pytest.mark.parametrize("periods", [0.37, 1.0, 3.71, 137.5])
def test_seek_is_the_definition_at_any_time_and_bounded(periods):
    p = CFG.guidance
    g = _core.Guidance(p, T)
    g.prepare()
    table = g.period_table
    t = periods * table.period
    before = g.rk4_steps
    g.seek(t)
    assert g.rk4_steps - before <= table.stride + 1 and g.t == t
    assert_reference(g.sigma_DN, p, t)


def test_seek_agrees_with_the_time_line_and_reset_back_is_bounded():
    """The evaluation from the definition and the controller's own time line
    (RK4 steps of one period at 10 Hz, 25,000 of them) agree to 1e-11; a
    reset a day back costs the bound, not a day of steps."""
    p = CFG.guidance
    line = _core.Guidance(p, 0.1)
    for t in np.arange(0.0, 2500.0 + 1e-9, 5.0):  # 50 steps a call: along the time line
        line.advance(t)
    assert line.seeks == 0 and line.rk4_steps == 25000
    g = _core.Guidance(p, 0.1)
    g.prepare()
    g.seek(2500.0)
    np.testing.assert_allclose(g.sigma_DN, line.sigma_DN, rtol=0, atol=1e-11)
    g.seek(DAY)
    before = g.rk4_steps
    g.reset(100.0)  # before its time: a new time line, to 100 s by the definition
    assert g.rk4_steps - before <= max(_core.GUIDANCE_MAX_CATCH_UP, g.period_table.stride + 1)
    assert_reference(g.sigma_DN, p, 100.0)


@pytest.mark.parametrize("freq, cos_amp", [(0.0, [0.02, 0.0, -0.03]), (0.01, [0.0, 0.0, 0.0])])
def test_a_constant_rate_is_a_closed_form(freq, cos_amp):
    """freq = 0 (omega = bias + cos_amp) or no oscillating amplitude: a
    rotation about a fixed axis, evaluated in closed form (no RK4 step)."""
    p = _core.GuidanceParams()
    p.omega_freq, p.omega_cos, p.omega_sin = freq, np.array(cos_amp), np.zeros(3)
    p.omega_bias = np.array([0.001, 0.004, 0.0])
    g = _core.Guidance(p, 0.1)
    assert g.period_table.kind == "constant"
    for t in (700.0, DAY):
        g.seek(t)
        assert g.rk4_steps == 0
        assert_reference(g.sigma_DN, p, t)


def test_a_period_too_long_to_tabulate_is_refused_with_the_way_out():
    p = _core.GuidanceParams()
    p.omega_freq = 1e-6  # a period of 72 days at 0.05 rad/s
    errs = _core.validate(p)
    assert len(errs) == 1 and "too slow for its rates" in errs[0] and "use freq = 0" in errs[0], errs
    p.omega_freq = 1e-3
    assert _core.validate(p) == []


# --------------------------------------------------------------------------- #
# The table of the report (old main: only the RK4 steps are counted there).


def _work_table() -> list[tuple[str, int, object, str]]:
    """(case, RK4 steps, law calls or None, mode and flags) of one step each."""
    rows = []

    def one(name, ctl, m):
        calls0 = ctl.counts.law_calls if hasattr(ctl, "counts") else None
        r0 = ctl.guidance.rk4_steps
        cmd = ctl.step(m)
        calls = ctl.counts.law_calls - calls0 if calls0 is not None else None
        rows.append((name, ctl.guidance.rk4_steps - r0, calls, f"mode {cmd.mode} flags {cmd.flags}"))

    for gap in (1.0, 10.0, 60.0, 600.0, DAY):
        ctl = _core.Controller(CFG)
        if hasattr(ctl, "prepare"):
            ctl.prepare()
        for k in range(10):
            ctl.step(meas(k * T))
        ctl.step(meas(10 * T, ok=False))
        one(f"re-engage after a gap of {gap:g} s", ctl, meas(10 * T + gap))
    for prepared in (False, True):
        for t0 in (3000.0, DAY):
            ctl = _core.Controller(CFG)
            if prepared and hasattr(ctl, "prepare"):
                ctl.prepare()
            one(f"late joiner at t = {t0:g} s, {'prepared' if prepared else 'unprepared'}", ctl, meas(t0))
    for name, t_next in (("jump +1000 s", 0.2 + 1000.0), ("step back to 0.1 s", 0.1)):
        ctl = _core.Controller(CFG)
        if hasattr(ctl, "prepare"):
            ctl.prepare()
        for k in range(201):
            ctl.step(meas(k * T))
        one(name, ctl, meas(t_next))
        zs = [ctl.step(meas(t_next + k * T)) for k in range(1, 2001)]
        z1 = max(float(np.abs(c.z1).max()) for c in zs)
        rows.append((f"  ... the next 2000 steps: max |z1| {z1:.3g}, NORMAL {sum(c.mode == 1 for c in zs)}",
                     0, None, f"flags of the last {zs[-1].flags}"))
    return rows


if __name__ == "__main__":
    print(f"{SCENARIO}: {CFG.control_rate_hz:g} Hz")
    for name, rk4, calls, what in _work_table():
        print(f"{name:64s} RK4 {rk4:>10d}  law calls {'n/a' if calls is None else calls:>4}  {what}")
