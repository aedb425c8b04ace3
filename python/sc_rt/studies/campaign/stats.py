"""Statistics of a campaign: the hold fraction with its exact (Clopper-Pearson)
interval, and Wilks tolerance bounds on worst-case metrics; for the
requirements (sc_rt.studies.campaign.requirements) the one-sided bounds,
the order statistic that bounds a quantile, and the runs a statement needs.

Wilks (one-sided, non-parametric): the k-th largest of n independent runs
is an upper bound of the p-quantile of a metric with confidence
P(Binomial(n, 1 - p) >= k). First order (k = 1, the maximum): confidence
1 - p^n, so 95 %/95 % needs n >= ln(0.05) / ln(0.95), i.e. 59 runs; with
more runs a higher order k (a less extreme sample) still holds.
"""

from __future__ import annotations

import math

__all__ = ["clopper_pearson", "clopper_pearson_lower", "hoeffding_lower", "quantile_upper_rank", "runs_needed",
           "wilks_confidence", "wilks_order", "wilks_runs", "tolerance_bound"]


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


def clopper_pearson_lower(k: int, n: int, confidence: float = 0.95) -> float:
    """Exact one-sided lower bound of a binomial proportion from k successes
    in n trials: the smallest p for which k or more successes are not
    unlikely, beta.ppf(1 - confidence, k, n - k + 1); 0 for k = 0 and
    (1 - confidence)^(1/n) for k = n (59 of 59 at 95 %: 0.9505)."""
    from scipy.stats import beta

    if n <= 0 or not 0 <= k <= n:
        raise ValueError(f"need 0 <= k <= n and n > 0, got k = {k}, n = {n}")
    if k == 0:
        return 0.0
    if k == n:
        return float((1.0 - confidence) ** (1.0 / n))
    return float(beta.ppf(1.0 - confidence, k, n - k + 1))


def hoeffding_lower(mean: float, n: int, confidence: float = 0.95) -> float:
    """One-sided lower bound of the mean of n independent values in [0, 1]
    (Hoeffding): mean - sqrt(ln(1 / (1 - confidence)) / (2 n)), at least 0."""
    return max(0.0, float(mean) - math.sqrt(math.log(1.0 / (1.0 - confidence)) / (2.0 * n)))


def quantile_upper_rank(n: int, p: float, confidence: float = 0.95) -> int:
    """The rank r (1-based, ascending) of the order statistic of n
    independent samples that bounds their p-quantile from above with the
    given confidence, the smallest r with P(Binomial(n, p) <= r - 1) >=
    confidence; 0 when not even the largest does (too few samples). It is
    the dual of ``clopper_pearson_lower``: the r-th smallest is <= b exactly
    when the lower bound of the fraction <= b is >= p."""
    from scipy.stats import binom

    if n <= 0:
        return 0
    r = int(binom.ppf(confidence, n, p)) + 1
    while r > 1 and binom.cdf(r - 2, n, p) >= confidence:  # the float ppf, made exact
        r -= 1
    while r <= n and binom.cdf(r - 1, n, p) < confidence:
        r += 1
    return r if r <= n else 0


def runs_needed(p: float, confidence: float = 0.95, failures: int = 0) -> int | None:
    """The fewest runs for "a fraction >= p of runs meet it, at this
    confidence" with ``failures`` runs failing: with none, the n with
    p^n <= 1 - confidence (59 for 95 %/95 %); with f, the Wilks order f + 1.
    None for p >= 1: no finite number of runs shows that every run would."""
    if p >= 1.0:
        return None
    return wilks_runs(p, confidence, order=failures + 1)
