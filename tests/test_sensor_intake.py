"""The controller's sensor intake (cpp/shell/sensor_intake.hpp) without LCM:
fed the samples the offline loop's sensors produce, in the order the
emulator publishes them, it gives the estimator exactly the offline
navigation's numbers (a second path through the same filter: a dropped,
reordered or repeated sample would change them); samples of another session,
repeated, out of order or not finite are counted and change nothing; a
controller that joins a run late has no estimate until its first star
tracker attitude; and the controller's configuration carries the filter's
noise model and the offline loop's initial estimate."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sc_rt import _core
from sc_rt.scenario.overrides import grid, initial_state
from sc_rt.scenario.reader import load_scenario
from sc_rt.scenario.tables.sensors import nav_config
from sc_rt.sim.sensed import NAV

ROOT = Path(__file__).resolve().parent.parent
SENSED = ROOT / "scenarios" / "ppc_feasible_10hz_sensors.toml"
SESSION = 1234


@pytest.fixture(scope="module")
def scn():
    return load_scenario(SENSED)


def _samples(scn, seconds=20.0):
    """The SensorSuite's samples over `seconds` from a slowly turning state, as
    (tick, kind, args) in the emulator's publishing order (gyro, star, tach per tick)."""
    nav = nav_config(scn.sensors, scn.run.plant_step)
    suite = _core.SensorSuite(nav.sensors)
    x = initial_state(scn)
    x[3:6] = [1e-3, -2e-3, 5e-4]
    h = scn.run.plant_step
    out, states = [], {}
    seq = [0, 0, 0]
    for i in range(int(round(seconds / h)) + 1):
        t = i * h
        xi = x.copy()
        xi[0:3] = _core.mrp_rotate_body(x[0:3], -np.asarray(x[3:6]) * t)  # a constant body rate
        states[i] = xi
        suite.tick(i, t, xi)
        if suite.gyro_new:
            out.append((i, "gyro", (seq[0], *suite.gyro)))
            seq[0] += 1
        if suite.star_new:
            out.append((i, "star", (seq[1], *suite.star)))
            seq[1] += 1
        if suite.tach_new:
            out.append((i, "tach", (seq[2], *suite.tach)))
            seq[2] += 1
    return nav, out, states


def _intake(scn):
    raw = scn.controller_config_msg().encode()
    enabled, use_est, mekf, sigma0, mag_R_SB = _core.nav_from_config_bytes(raw)
    assert enabled and mag_R_SB is None  # no [sensors.magnetometer]
    return _core.SensorIntake(mekf, use_est, sigma0)


def _offer(intake, item, session=SESSION):
    _, kind, args = item
    getattr(intake, "offer_" + kind)(session, *args)


def _truth(x, t):
    return _core.Measurement(t, x[0:3], x[3:6], x[6:10])


def test_config_carries_the_filter_and_the_offline_initial_estimate(scn):
    raw = scn.controller_config_msg().encode()
    enabled, use_est, mekf, sigma0, _mag = _core.nav_from_config_bytes(raw)
    ref = nav_config(scn.sensors, scn.run.plant_step)
    assert enabled and use_est == ref.use_estimate
    for k in ("arw", "rrw", "bias_sigma", "bias_tau", "quantization", "sigma_cross", "sigma_boresight",
              "initial_attitude_sigma", "initial_bias_sigma", "degraded_after", "history"):
        assert getattr(mekf, k) == getattr(ref.mekf, k), k
    navi = _core.Navigation(ref)
    navi.reset(initial_state(scn))
    assert np.array_equal(sigma0, navi.filter.state.sigma)  # bitwise: the same draw
    # a scenario without [sensors]: disabled
    plain = load_scenario(ROOT / "scenarios" / "ppc_feasible_10hz.toml")
    assert _core.nav_from_config_bytes(plain.controller_config_msg().encode())[0] is False


def _run(scn, items, states, extra=None):
    """Feed items tick by tick; measure at every control instant: telemetry rows."""
    intake = _intake(scn)
    n_sub = grid(scn)[1]
    rows = []
    by_tick: dict[int, list] = {}
    for it in items:
        by_tick.setdefault(it[0], []).append(it)
    for i in sorted(states):
        for it in by_tick.get(i, []):
            _offer(intake, it)
            if extra:
                extra(intake, it)
        if i % n_sub == 0:
            intake.use(SESSION, i * scn.run.plant_step)
            rows.append(intake.measure(_truth(states[i], i * scn.run.plant_step))[1])
    return intake, np.array(rows)


def _reference(scn, nav, states):
    """The offline navigation over the same states (Navigation.tick every plant step)."""
    navi = _core.Navigation(nav)
    navi.reset(initial_state(scn))
    n_sub = grid(scn)[1]
    rows = []
    for i in sorted(states):
        navi.tick(i, i * scn.run.plant_step, states[i])
        if i % n_sub == 0:
            rows.append(navi.measure(i * scn.run.plant_step, states[i])[1])
    return np.array(rows)


EST = [NAV[k] for k in ("sigma_BN_est", "bias_est", "P_diag", "innovation", "nis", "nav_flags")]


def _est(rows):
    return np.concatenate([rows[:, s] for s in EST], axis=1)


def test_intake_fed_in_publishing_order_equals_the_offline_navigation_bitwise(scn):
    nav, items, states = _samples(scn)
    intake, got = _run(scn, items, states)
    ref = _reference(scn, nav, states)
    assert np.array_equal(_est(got), _est(ref), equal_nan=True)
    c = intake.counts()
    n = [sum(1 for it in items if it[1] == k) for k in ("gyro", "star", "tach")]
    assert c.used == tuple(n) and c.rejected == 0
    assert n[1] > 10  # the comparison saw star tracker updates


def test_foreign_repeated_and_bad_samples_are_counted_and_change_nothing(scn):
    nav, items, states = _samples(scn)
    bad = {"n": 0}

    def hostile(intake, it):
        _, kind, args = it
        seq = args[0]
        if seq % 7 == 3:  # another bench's sample of the same kind
            getattr(intake, "offer_" + kind)(SESSION + 1, *args)
        if seq % 5 == 1:  # a repeat, and an older one
            _offer(intake, it)
            if seq > 1:
                getattr(intake, "offer_" + kind)(SESSION, seq - 1, *args[1:])
        if kind == "gyro" and seq % 11 == 4:  # non-finite
            intake.offer_gyro(SESSION, seq + 1000, args[1], np.array([np.nan, 0.0, 0.0]))
            bad["n"] += 1
        if kind == "gyro" and seq % 13 == 6:  # a gyro_t output kind nobody defined (0 rate, 1 mean rate)
            intake.offer_gyro(SESSION, seq + 2000, args[1], args[2], 7)
            bad["n"] += 1
        if kind == "star" and seq % 3 == 0:  # not an MRP, exposure after delivery
            intake.offer_star(SESSION, seq + 1000, args[1], args[2], np.array([2.0, 0.0, 0.0]))
            intake.offer_star(SESSION, seq + 1000, args[2] + 1.0, args[2], args[3])
            bad["n"] += 2
        intake.malformed()

    intake, got = _run(scn, items, states, extra=hostile)
    assert np.array_equal(_est(got), _est(_reference(scn, nav, states)), equal_nan=True)
    c = intake.counts()
    assert c.invalid == bad["n"] and c.malformed == len(items)
    assert c.out_of_order > 0
    n_foreign = sum(1 for it in items if it[2][0] % 7 == 3)
    assert c.foreign + intake.queued == n_foreign > 0  # waiting, or dropped when the queue was full
    n = [sum(1 for it in items if it[1] == k) for k in ("gyro", "star", "tach")]
    assert c.used == tuple(n)


def test_samples_before_the_first_state_wait_for_it(scn):
    """The run's first samples go out just before state 0: queued, applied at follow()."""
    nav, items, states = _samples(scn, seconds=2.0)
    intake = _intake(scn)
    first = [it for it in items if it[0] == 0]
    assert first and not intake.ready
    for it in first:
        _offer(intake, it)
    assert intake.counts().used == (0, 0, 0)
    intake.use(SESSION, 0.0)
    assert intake.ready and sum(intake.counts().used) == len(first)


def test_samples_later_than_the_state_used_wait_for_a_later_state(scn):
    """Real time: a controller acting on state k while the next period's
    samples are already in measures at t_k from the samples up to t_k only
    (the same numbers as one that got exactly those), and holds the rest."""
    nav, items, states = _samples(scn, seconds=3.0)
    n_sub = grid(scn)[1]
    h = scn.run.plant_step
    ctrl = sorted(i for i in states if i % n_sub == 0)
    on_time, ahead = _intake(scn), _intake(scn)
    rows_on_time, rows_ahead = [], []
    for a, b in zip(ctrl, ctrl[1:]):
        for it in items:
            if (a == 0 and it[0] == 0) or (a > 0 and a - n_sub < it[0] <= a):
                _offer(on_time, it)  # the samples up to t_a, then state a
            if (a == 0 and it[0] <= b) or (a > 0 and a < it[0] <= b):
                _offer(ahead, it)  # the samples up to t_b already in when state a is used
        on_time.use(SESSION, a * h)
        ahead.use(SESSION, a * h)
        rows_on_time.append(on_time.measure(_truth(states[a], a * h))[1])
        rows_ahead.append(ahead.measure(_truth(states[a], a * h))[1])
    assert np.array_equal(_est(np.array(rows_ahead)), _est(np.array(rows_on_time)), equal_nan=True)
    assert ahead.queued > 0 and on_time.queued == 0  # the last period's samples still wait


def test_a_late_joiner_waits_for_its_first_star_tracker_attitude(scn):
    nav, items, states = _samples(scn, seconds=20.0)
    intake = _intake(scn)
    intake.use(SESSION, 20.0)  # it acts on a state at t = 20 s
    late = [it for it in items if it[0] >= 500]  # joined at t = 5 s: seqs > 0
    first_star = next(it for it in late if it[1] == "star")
    for it in late:
        _offer(intake, it)
        if it is first_star:
            break
        assert not intake.ready
    assert intake.ready
    c = intake.counts()
    assert c.before_fix == sum(1 for it in late[: late.index(first_star)] if it[1] == "gyro") > 0
    # the estimate restarts from that attitude at its exposure time
    _, te, _, sig = first_star[2]
    assert intake.estimator.filter.state.t == te
    assert np.array_equal(intake.estimator.filter.state.sigma, sig)
