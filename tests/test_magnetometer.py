"""The magnetometer model (issue #43 item 3; sc_rt/sensors.hpp Magnetometer), checked against
what nobody here wrote: the white noise's sample variance against the chi-square distribution
of scipy.stats (and its axes uncorrelated, its mean zero by the normal distribution), the
quantisation exactly (every output an integer multiple of the LSB, within half an LSB of the
unquantised value, which the same seed gives), the misalignment / scale matrix and the
body-to-sensor rotation applied exactly, the bias, the range, and the seed's reproducibility.
All fail on the old main (no such bindings)."""

from __future__ import annotations

import numpy as np
from scipy import stats
from scipy.spatial.transform import Rotation

from sc_rt import _core

B_B = np.array([1.2e-5, -2.5e-5, 3.1e-5])  # [T]


def _params(**kw) -> _core.MagnetometerParams:
    p = _core.MagnetometerParams()
    p.enabled = True
    for k, v in kw.items():
        setattr(p, k, v)
    return p


def test_noise_statistics_against_chi_square():
    sigma = 50e-9  # [T] 50 nT
    n = 20000
    mag = _core.Magnetometer(_params(noise=sigma), 7)
    x = np.array([mag.sample(B_B) for _ in range(n)]) - B_B
    for k in range(3):
        stat = (n - 1) * np.var(x[:, k], ddof=1) / sigma**2
        lo, hi = stats.chi2.ppf([0.0005, 0.9995], n - 1)  # two-sided 0.1 % per axis
        assert lo < stat < hi, (k, stat, lo, hi)
        z = np.mean(x[:, k]) / (sigma / np.sqrt(n))
        assert abs(z) < stats.norm.ppf(0.9995)
    c = np.corrcoef(x.T)
    assert np.max(np.abs(c[np.triu_indices(3, 1)])) < 4.0 / np.sqrt(n)  # ~ 0.03: 4 sigma of the null


def test_quantisation_exact():
    lsb = 13e-9
    q = _core.Magnetometer(_params(noise=40e-9, lsb=lsb), 11)
    raw = _core.Magnetometer(_params(noise=40e-9), 11)  # the same seed: the same draws
    for _ in range(500):
        y, r = q.sample(B_B), raw.sample(B_B)
        np.testing.assert_array_equal(y, lsb * np.round(y / lsb))  # integer multiples of the LSB
        np.testing.assert_array_equal(y, lsb * np.round(r / lsb))
        assert np.all(np.abs(y - r) <= 0.5 * lsb * (1 + 1e-12))


def test_misalignment_rotation_bias_and_range_exact():
    R_SB = Rotation.from_euler("zyx", [20.0, -10.0, 5.0], degrees=True).as_matrix()
    M = np.array([[1.01, 0.002, -0.003], [0.001, 0.98, 0.004], [-0.002, 0.003, 1.02]])
    bias = np.array([1e-7, -2e-7, 3e-7])
    mag = _core.Magnetometer(_params(M=M, R_SB=R_SB, bias=bias), 1)
    np.testing.assert_allclose(mag.sample(B_B), M @ R_SB @ B_B + bias, rtol=1e-14, atol=1e-22)
    sat = _core.Magnetometer(_params(range=2e-5), 1)
    np.testing.assert_array_equal(sat.sample(B_B), [1.2e-5, -2e-5, 2e-5])


def test_seeded_reproducible_and_reset():
    a = _core.Magnetometer(_params(noise=1e-7), 5)
    b = _core.Magnetometer(_params(noise=1e-7), 5)
    c = _core.Magnetometer(_params(noise=1e-7), 6)
    xa = [a.sample(B_B) for _ in range(5)]
    np.testing.assert_array_equal(xa, [b.sample(B_B) for _ in range(5)])
    assert not np.array_equal(xa[0], c.sample(B_B))
    a.reset()
    np.testing.assert_array_equal(a.sample(B_B), xa[0])
    # its own stream of the seed: the gyro's stream (1) of the same seed differs
    assert _core.Magnetometer(_params(noise=1.0), 5).sample(np.zeros(3))[0] == _core.Rng(5, 5).normal()
