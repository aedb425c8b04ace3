"""Statistics of a campaign: the hold fraction with its exact (Clopper-Pearson)
interval, and Wilks tolerance bounds on worst-case metrics.

Wilks (one-sided, non-parametric): the k-th largest of n independent runs
is an upper bound of the p-quantile of a metric with confidence
P(Binomial(n, 1 - p) >= k). First order (k = 1, the maximum): confidence
1 - p^n, so 95 %/95 % needs n >= ln(0.05) / ln(0.95), i.e. 59 runs; with
more runs a higher order k (a less extreme sample) still holds.
"""

from __future__ import annotations

import math

__all__ = ["clopper_pearson", "wilks_confidence", "wilks_order", "wilks_runs", "tolerance_bound"]


def clopper_pearson(k: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Exact two-sided interval of a binomial proportion k / n (beta quantiles)."""
    from scipy.stats import beta

    if n <= 0 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n > 0, got k = {k}, n = {n}")
    a = 1.0 - confidence
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def wilks_confidence(n: int, k: int, p: float) -> float:
    """Confidence that the k-th largest of n runs bounds the p-quantile from above."""
    from scipy.stats import binom

    return float(binom.sf(k - 1, n, 1.0 - p))  # P(at least k of n runs above the quantile)


def wilks_runs(p: float = 0.95, confidence: float = 0.95, order: int = 1) -> int:
    """Fewest runs for an order-``order`` one-sided Wilks bound (59 for 95/95, first order)."""
    if order == 1:  # closed form: 1 - p^n >= confidence
        n = math.ceil(math.log(1.0 - confidence) / math.log(p) - 1e-12)
        return n
    n = order
    while wilks_confidence(n, order, p) < confidence:
        n += 1
    return n


def wilks_order(n: int, p: float = 0.95, confidence: float = 0.95) -> int:
    """The highest order k whose k-th largest of n runs is a valid bound (0: too few runs)."""
    from scipy.stats import binom

    if n < wilks_runs(p, confidence):
        return 0
    # P(Binom(n, 1-p) >= k) >= confidence  <=>  binom.cdf(k - 1) <= 1 - confidence
    k = int(binom.ppf(1.0 - confidence, n, 1.0 - p))
    while k >= 1 and wilks_confidence(n, k, p) < confidence:
        k -= 1
    while wilks_confidence(n, k + 1, p) >= confidence:
        k += 1
    return max(k, 1)


def tolerance_bound(values: list[float], p: float = 0.95, confidence: float = 0.95) -> dict:
    """The one-sided Wilks upper tolerance bound of ``values`` (or why there is none)."""
    n = len(values)
    need = wilks_runs(p, confidence)
    if n < need:
        return {"bound": None, "order": 0, "runs": n,
                "why": f"{need} runs needed for a {100 * p:g} %/{100 * confidence:g} % bound"}
    k = wilks_order(n, p, confidence)
    return {"bound": float(sorted(values)[n - k]), "order": k, "runs": n,
            "confidence": wilks_confidence(n, k, p)}
