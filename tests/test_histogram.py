"""The controller's whole-run statistics (issue #31, item 3): a fixed-size
log-linear histogram (cpp/shell/histogram.hpp) instead of a sample buffer
that stopped after 2^20 steps (17.5 min at 1 kHz, its exit percentiles
describing the start only). Checked against numpy's nearest-rank
percentiles of the same samples: within 1/128 relative (2^7 sub-buckets per
octave), the count and the maximum exact, the size fixed."""

from __future__ import annotations

import numpy as np
import pytest

from sc_rt import _core


def _nearest_rank(v: np.ndarray, p: float) -> float:
    return float(np.percentile(v, 100 * p, method="inverted_cdf"))


@pytest.mark.parametrize("dist", ["lognormal", "uniform", "heavy", "integers"])
def test_quantiles_against_numpy(dist):
    rng = np.random.default_rng(7)
    v = {"lognormal": rng.lognormal(3.0, 1.0, 200_000),  # [us] tens of us with a long tail
         "uniform": rng.uniform(0.0, 1000.0, 100_000),
         "heavy": np.concatenate([rng.uniform(5, 6, 99_000), rng.uniform(5e5, 2e6, 1_000)]),
         "integers": rng.integers(0, 50, 10_000) / 1e3}[dist]  # whole ns: below 128 ns, exact
    h = _core.LogHistogram()
    h.add_many(v.tolist())
    assert h.count == v.size and h.max == float(v.max())
    assert h.mean == pytest.approx(float(v.mean()), rel=1e-9)
    for p in (0.0, 0.01, 0.5, 0.9, 0.99, 0.999, 1.0):
        want = _nearest_rank(v, p)
        got = h.quantile(p)
        tol = (1.0 / 128) * want + 0.5e-3  # half a ns of rounding to whole ns
        assert abs(got - want) <= tol, (dist, p, got, want)


def test_no_cap_and_fixed_size():
    """Beyond the old 2^20-sample cap the statistics still follow the run:
    a run whose late part is slower shows it in the quantiles and the max."""
    h = _core.LogHistogram()
    h.add_many([10.0] * (1 << 20))
    h.add_many([1000.0] * ((1 << 20) + 10))  # the second half: slower
    assert h.count == (1 << 21) + 10 and h.max == 1000.0
    assert h.quantile(0.99) == pytest.approx(1000.0, rel=1 / 128)
    assert h.quantile(0.25) == pytest.approx(10.0, rel=1 / 128)
    assert _core.LogHistogram.BUCKETS == (64 - 7 + 1) * 128  # fixed: 59 kB of counts, whatever the run's length


def test_bad_samples():
    h = _core.LogHistogram()
    for x in (-5.0, float("nan"), 0.0):
        h.add(x)
    assert h.count == 3 and h.max == 0.0 and h.quantile(0.5) == 0.0
    assert _core.LogHistogram().quantile(0.5) == 0.0
