"""Magnetorquers (issue #43 item 3; cpp/include/sc_rt/magnetorquer.hpp): the torque's sign
against Basilisk's MtbEffector convention (tau = -B~ G mu, i.e. m x B; its
src/simulation/dynamics/MtbEffector/MtbEffector.cpp in AVSLab/basilisk) with numbers worked by
hand, per-rod clipping, the three rod faults, Basilisk's dipoleMapping cases
(src/fswAlgorithms/effectorInterfaces/dipoleMapping/_UnitTest/test_dipoleMapping.py: a trivial
steering matrix, two rods at 45 deg) and the allocation's direction-keeping saturation. All fail
on the old main (no such bindings)."""

from __future__ import annotations

import numpy as np
import pytest

from sc_rt import _core

rng = np.random.default_rng(3)


def _params(G, dmax):
    p = _core.MagnetorquerParams()
    p.G_B = np.asarray(G, dtype=float)
    p.dipole_max = np.asarray(dmax, dtype=float)
    return p


def test_torque_sign_by_hand():
    """A rod along x with 1 A m^2 in a field along y (1e-5 T): x cross y = +z, so tau = +1e-5 z
    (Basilisk: -B~ m = -(B x m) = m x B)."""
    q = _core.Magnetorquers(_params(np.eye(3), [10.0] * 3))
    o = q.update(np.array([1.0, 0.0, 0.0]), np.array([0.0, 1e-5, 0.0]))
    np.testing.assert_array_equal(o.torque_B, [0.0, 0.0, 1e-5])
    B = np.array([2e-5, -1e-5, 3e-5])
    m = np.array([1.0, 2.0, 3.0])
    # -B~ m written out with Basilisk's tilde matrix
    B_tilde = np.array([[0.0, -B[2], B[1]], [B[2], 0.0, -B[0]], [-B[1], B[0], 0.0]])
    np.testing.assert_allclose(_core.magnetic_torque(m, B), -B_tilde @ m, rtol=1e-15, atol=0)


def test_per_rod_clip_and_skewed_axes():
    G = rng.normal(size=(3, 4))
    G /= np.linalg.norm(G, axis=0)
    q = _core.Magnetorquers(_params(G, [1.0, 2.0, 3.0, 4.0]))
    o = q.update(np.array([5.0, -0.5, -7.0, 4.0]), np.array([1e-5, 2e-5, -3e-5]))
    np.testing.assert_array_equal(o.dipole, [1.0, -0.5, -3.0, 4.0])
    assert o.clipped == 0b0101
    np.testing.assert_allclose(o.m_B, G @ o.dipole, rtol=1e-15)
    np.testing.assert_allclose(o.torque_B, np.cross(G @ o.dipole, [1e-5, 2e-5, -3e-5]), rtol=1e-14)


def test_faults_dead_stuck_reversed_live():
    q = _core.Magnetorquers(_params(np.eye(3), [10.0] * 3))
    B = np.array([1e-5, 2e-5, 3e-5])
    cmd = np.array([4.0, -12.0, 6.0])
    np.testing.assert_array_equal(q.update(cmd, B).dipole, [4.0, -10.0, 6.0])
    q.set_fault(0, _core.RodFault.Dead)
    q.set_fault(1, _core.RodFault.Reversed)
    q.set_fault(2, _core.RodFault.Stuck, 2.5)
    o = q.update(cmd, B)
    np.testing.assert_array_equal(o.dipole, [0.0, 10.0, 2.5])  # the reversed rod: clipped, then reversed
    np.testing.assert_array_equal(o.torque_B, np.cross([0.0, 10.0, 2.5], B))
    assert q.fault(2) == _core.RodFault.Stuck and _core.rod_fault_name(q.fault(1)) == "reversed"
    q.set_fault(1, _core.RodFault.Healthy)
    assert q.update(cmd, B).dipole[1] == -10.0
    with pytest.raises(ValueError, match="rod 3 outside"):
        q.set_fault(3, _core.RodFault.Dead)
    # a rod saturates: it sticks within its limit (10 A m^2), and a refused fault changes nothing
    q.set_fault(2, _core.RodFault.Stuck, -10.0)
    with pytest.raises(ValueError, match="rod 2 stuck at 10.5 A m\\^2, beyond its dipole_max 10 A m\\^2"):
        q.set_fault(2, _core.RodFault.Stuck, 10.5)
    assert q.update(cmd, B).dipole[2] == -10.0


def test_residual_dipole_is_a_torque_like_any_other():
    m_res = np.array([0.1, -0.05, 0.2])  # [A m^2]
    B = np.array([-2e-5, 1e-5, 4e-5])
    np.testing.assert_array_equal(_core.magnetic_torque(m_res, B), np.cross(m_res, B))


def test_basilisk_dipole_mapping_cases():
    """dipoleMapping's TEST 1 (identity steering: [1, 2, 3] -> [1, 2, 3]) and TEST 2 (two rods at
    45 deg in the x-y plane: pinv(Gt) [1, 2, 3]), with limits that do not bind (1e3)."""
    a = _core.DipoleAllocator(_params(np.eye(3), [1e3] * 3))
    np.testing.assert_allclose(a.allocate(np.array([1.0, 2.0, 3.0])).dipole, [1.0, 2.0, 3.0], rtol=1e-15)
    beta = np.pi / 4
    Gt = np.array([[np.cos(beta), -np.sin(beta)], [np.sin(beta), np.cos(beta)], [0.0, 0.0]])
    a2 = _core.DipoleAllocator(_params(Gt, [1e3] * 2))
    d = a2.allocate(np.array([1.0, 2.0, 3.0])).dipole
    np.testing.assert_allclose(d, np.linalg.pinv(Gt) @ [1.0, 2.0, 3.0], rtol=1e-12)
    np.testing.assert_allclose(d, [3 / np.sqrt(2), 1 / np.sqrt(2)], rtol=1e-12)  # by hand
    np.testing.assert_array_equal(a2.allocate(np.zeros(3)).dipole, [0.0, 0.0])


def test_allocation_saturation_keeps_the_direction():
    G = rng.normal(size=(3, 4))
    G /= np.linalg.norm(G, axis=0)
    dmax = np.array([1.0, 2.0, 0.5, 3.0])
    a = _core.DipoleAllocator(_params(G, dmax))
    for _ in range(50):
        m = rng.normal(size=3) * 5.0
        r = a.allocate(m)
        free = np.linalg.pinv(G) @ m
        s = min(1.0, np.min(dmax / np.abs(free)))
        assert r.scale == pytest.approx(s, rel=1e-12)
        np.testing.assert_allclose(r.dipole, s * free, rtol=1e-11, atol=1e-14)
        assert np.all(np.abs(r.dipole) <= dmax * (1 + 1e-14))
        np.testing.assert_allclose(r.m_B, s * m, rtol=1e-11, atol=1e-13)  # four rods span B: direction kept


def test_validation_names_the_values():
    with pytest.raises(ValueError, match=r"rod 2's axis is not a unit vector \(norm 2\)"):
        _core.Magnetorquers(_params([[1.0, 0.0], [0.0, 2.0], [0.0, 0.0]], [1.0, 1.0]))
    with pytest.raises(ValueError, match="dipole_max of rod 1 must be finite and > 0, got -1"):
        _core.Magnetorquers(_params(np.eye(3), [-1.0, 1.0, 1.0]))
    with pytest.raises(ValueError, match="1 <= N <= 6, got 3 x 7"):
        _params(np.ones((3, 7)) / np.sqrt(3), [1.0] * 7)
    q = _core.Magnetorquers(_params(np.eye(3), [1.0] * 3))
    with pytest.raises(ValueError, match="2 dipole commands for 3 rods"):
        q.update(np.zeros(2), np.zeros(3))
