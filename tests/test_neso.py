"""Observer (22): convergence on a synthetic system with a known
disturbance, behaviour near zero error, condition (26)."""

import numpy as np
import pytest

from sc_rt import _core

import refmath as ref


def test_paper_gains_satisfy_condition_26_in_both_readings():
    p = _core.NesoParams()
    margin = _core.neso_condition_26(p)
    assert np.all(margin > 0)
    # independently, both readings of the extraction
    k1, k2, k3, k4, a = 0.2, 0.03, 0.08, 0.06, 0.7
    common = (a + 1) ** 2 * k1**2 * k2**2
    assert k3 * k4 > k2**2 * k3 / a + common
    assert k3 * k4 > k2**2 * k3 * a + common
    np.testing.assert_allclose(margin, k3 * k4 - max(k2**2 * k3 / a, k2**2 * k3 * a) - common)


def test_condition_26_fails_for_weak_k4():
    p = _core.NesoParams()
    p.k4 = np.array([1e-4, 0.06, 0.06])
    m = _core.neso_condition_26(p)
    assert m[0] < 0 and m[1] > 0


class Cosines:
    """delta(t) = a cos(w t) + b per axis, with its exact integral (x2)."""

    def __init__(self, a, w, b):
        self.a, self.w, self.b = (np.asarray(v, float) for v in (a, w, b))

    def __call__(self, t):
        return self.a * np.cos(self.w * t) + self.b

    def integral(self, t):
        return self.a * np.sin(self.w * t) / self.w + self.b * t


def simulate_observer(p, delta, h, T):
    """x2_dot = A + Bu + delta(t) with A = 0, Bu = 0 and x2 exact."""
    n = int(round(T / h))
    obs = _core.Neso(p)
    obs.reset(np.zeros(3), np.zeros(3))
    ts = np.arange(n + 1) * h
    zero = np.zeros(3)
    err = np.empty((n, 3))
    for k in range(n):
        obs.update(h, zero, zero, delta.integral(ts[k]), delta.integral(ts[k + 1]), zero)
        err[k] = obs.z2 - delta(ts[k + 1])
    return ts[1:], err


def test_z2_converges_to_a_smooth_disturbance():
    # the paper's disturbance scale: 1e-3 N m over ~10 kg m^2 -> ~5e-4 rad/s^2
    delta = Cosines([5e-4, -3e-4, 0.0], [0.02, 0.025, 1.0], [0.0, 0.0, 3e-4])
    t, err = simulate_observer(_core.NesoParams(), delta, 0.1, 300.0)
    initial = np.abs(delta(0.0)).max()
    late = np.abs(err[t > 200]).max()
    # converges: error at the end far below the disturbance itself
    assert late < 0.05 * initial, late
    assert np.all(np.isfinite(err))


def test_error_floor_shrinks_with_the_step():
    delta = Cosines([5e-4, 0.0, 0.0], [0.02, 1.0, 1.0], [0.0, 0.0, 2e-4])
    floors = []
    for h in (0.1, 0.01):
        t, err = simulate_observer(_core.NesoParams(), delta, h, 300.0)
        floors.append(np.abs(err[t > 250]).max())
    assert floors[1] < floors[0], floors


def test_bounded_limit_cycle_near_zero_error():
    # start exactly at the truth with no disturbance: the non-Lipschitz
    # sig^(2 alpha - 1) term must not blow up; a tiny perturbation stays tiny
    p = _core.NesoParams()
    obs = _core.Neso(p)
    obs.reset(np.array([1e-12, -1e-12, 0.0]), np.zeros(3))
    zero = np.zeros(3)
    peak = 0.0
    for _ in range(3000):
        obs.update(0.1, zero, zero, zero, zero, zero)
        peak = max(peak, np.abs(obs.z1).max(), np.abs(obs.z2).max())
        assert np.all(np.isfinite(obs.z1)) and np.all(np.isfinite(obs.z2))
    # the discrete limit cycle of a finite-time observer: amplitude set by
    # the step, (k3 h^2)^(1/(2 - 2 alpha)) ~ 1e-5 here; far from a blow-up
    assert peak < 1e-3, peak


def test_exactly_zero_error_stays_zero():
    obs = _core.Neso(_core.NesoParams())
    obs.reset(np.zeros(3), np.zeros(3))
    for _ in range(100):
        obs.update(0.1, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
    assert np.all(obs.z1 == 0) and np.all(obs.z2 == 0)


def test_update_matches_reference(rng):
    p = _core.NesoParams()
    p.substeps = 3
    n = dict(k1=np.array(p.k1), k2=np.array(p.k2), k3=np.array(p.k3), k4=np.array(p.k4), alpha=p.alpha)
    obs = _core.Neso(p)
    z1, z2 = rng.normal(size=3) * 1e-2, rng.normal(size=3) * 1e-3
    obs.reset(z1, z2)
    for _ in range(50):
        A0, A1, x0, x1, Bu = (rng.normal(size=3) * 1e-2 for _ in range(5))
        obs.update(0.1, A0, A1, x0, x1, Bu)
        z1, z2 = ref.neso_update(n, z1, z2, 0.1, A0, A1, x0, x1, Bu, 3)
        np.testing.assert_allclose(obs.z1, z1, rtol=1e-12, atol=1e-16)
        np.testing.assert_allclose(obs.z2, z2, rtol=1e-12, atol=1e-16)


@pytest.mark.parametrize("field, value, fragment", [
    ("alpha", 0.3, "alpha must be in [0.5, 1]"),
    ("substeps", 0, "substeps must be in [1, 10000]"),
    ("k3", np.array([0.08, -1.0, 0.08]), "NESO k3 must be finite and > 0"),
])
def test_invalid_parameters_raise(field, value, fragment):
    p = _core.NesoParams()
    setattr(p, field, value)
    with pytest.raises(ValueError, match=fragment.replace("[", r"\[").replace("]", r"\]")):
        _core.Neso(p)
