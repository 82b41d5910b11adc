"""How large is the difference of the response law, with an interval, and is it small enough?

**Effect.** Per response feature ``j`` (in its unit per second, e.g. m/s² for a speed), the
*response deviation*

    E_j = √( Σ_s w_s [ (μ_A,s − μ_B,s)² + (σ_A,s − σ_B,s)² ] )

over the states ``s`` both sides visit at least ``MIN_TRANSITIONS`` times, ``w_s`` the pooled
share of their transitions, ``μ``/``σ`` the mean and standard deviation of the adjusted response
(:mod:`simcred.compare.transitions`) in that state. Per state the bracket is the squared
2-Wasserstein distance of the two normal laws with those moments: a bias, a delay (a shifted
conditional mean), a gain or a variance change all enter, in the feature's own unit. It estimates
a property of the two response laws, so it does not grow with the number of runs (the paper's
distance, a count of rejected tests, does). ``shift_j = Σ_s w_s (μ_A,s − μ_B,s)`` is the signed
average bias.

**Interval.** Cluster bootstrap over the design's units (runs or groups within each side, whole
pairs) [1], [2]; the basic (reverse-percentile) interval ``[2Ê − q_{1−a/2}, 2Ê − q_{a/2}]``
corrects the plug-in's upward bias to first order [3] (clamped at 0).

**Equivalence** [4], [5], [6]. H0: ``E_j ≥ δ_j`` for some declared margin; H1: ``E_j < δ_j``
for all. Rejected (equivalence shown) when every one-sided upper ``1 − α`` bound
``2Ê − q_α`` lies below its margin: an intersection–union test, level α without adjustment.
Little data gives wide bounds and "not shown equivalent", never "equivalent".

**Is there any deviation?** ``pvalue``: the permutation p-value of ``Ê`` itself under the
design's assignments (the states that enter fixed): exact when the two response laws are the
same, whatever the sample size, and sensitive to changes of sign between states (an RMS, unlike a
pooled mean). A caller that declares "beyond the margin" can require it besides the bootstrap
lower bound, so that a candidate with the reference's own law is never declared beyond at more
than the test's level, however few units there are.

**Detectable effect.** ``mde_j = (z_{1−α/2} + z_{0.8}) · se(shift_j)``: the uniform shift of the
response that a test of the mean response would detect with 80 % power, with the bootstrap
standard error of ``shift_j`` (a normal approximation).

References
----------
[1] Field & Welsh, Bootstrapping clustered data, JRSS B 69, 2007.
[2] Davison & Hinkley, Bootstrap Methods and their Application, CUP, 1997 (sec. 3.8).
[3] Efron & Tibshirani, An Introduction to the Bootstrap, Chapman & Hall, 1993 (ch. 10, 13).
[4] Schuirmann, A comparison of the two one-sided tests procedure..., J. Pharmacokin. Biopharm.
    15, 1987.
[5] Wellek, Testing Statistical Hypotheses of Equivalence and Noninferiority, 2nd ed., CRC, 2010.
[6] Robinson & Froese, Model validation using equivalence tests, Ecol. Modelling 176, 2004.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from scipy.stats import norm

from simcred.compare.design import Design
from simcred.compare.response import unit_sums
from simcred.compare.runs import exceedance_pvalues
from simcred.compare.transitions import Transitions
from simcred.errors import OptionError

#: Transitions per side before a state enters the effect.
MIN_TRANSITIONS = 10
POWER = 0.8


@dataclass(frozen=True, slots=True)
class FeatureEffect:
    """The response deviation of one feature, its interval and what the data could detect.

    ``estimate``: bias-corrected (``2Ê − mean(E*)``, at least 0); ``plugin``: ``Ê`` itself;
    ``low``/``high``: basic bootstrap interval; ``upper``/``lower``: one-sided ``1 − α`` bounds
    (``upper`` is the equivalence test's); ``shift``: signed mean bias with its interval;
    ``mde``: detectable uniform shift. ``replicates``: the bootstrap estimates ``E*`` (not
    written to JSON), from which :meth:`bounds` gives one-sided bounds at any other level.
    """

    feature: str
    unit: str
    estimate: float
    plugin: float
    low: float
    high: float
    upper: float
    shift: float
    shift_low: float
    shift_high: float
    mde: float
    margin: float | None = None
    equivalent: bool | None = None
    lower: float = float("nan")
    pvalue: float = float("nan")
    replicates: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False,
                                   compare=False)

    def bounds(self, alpha: float) -> tuple[float, float]:
        """One-sided ``1 − alpha`` lower and upper bounds (basic bootstrap, clamped at 0);
        NaN when not estimable."""
        if len(self.replicates) == 0 or not np.isfinite(self.plugin):
            return float("nan"), float("nan")
        q_low, q_high = np.quantile(self.replicates, [alpha, 1 - alpha])
        return (float(max(2 * self.plugin - q_high, 0.0)),
                float(max(2 * self.plugin - q_low, 0.0)))


@dataclass(frozen=True, slots=True)
class EffectSummary:
    """Effects of all response features; ``equivalent``: every margin met (None: no margin).
    ``states``: how many states entered (0: not estimable, every estimate NaN)."""

    level: float
    replicates: int
    states: int
    features: tuple[FeatureEffect, ...]
    equivalent: bool | None


_POWERS = {"": "²", "²": "³", "^2": "^3"}


def rate_unit(unit: str | None) -> str:
    """The unit of a rate of change of a quantity in ``unit``: ``m`` → ``m/s``, ``m/s`` →
    ``m/s²``, ``m/s²`` → ``m/s³``; no unit → ``1/s``."""
    if not unit or unit == "dimensionless":
        return "1/s"
    for power, higher in _POWERS.items():
        if power and unit.endswith(f"/s{power}") or not power and unit.endswith("/s"):
            return f"{unit[:len(unit) - len(power)]}{higher}"
    return f"{unit}/s"


def check_margins(margin: Mapping[str, float] | float | None, response: tuple[str, ...]
                  ) -> tuple[tuple[str, float], ...]:
    """``{feature: δ}`` (or one δ for every response feature) as sorted pairs; δ > 0."""
    if margin is None:
        return ()
    pairs = {name: margin for name in response} if isinstance(margin, int | float) \
        else dict(margin)
    out = []
    for name, value in pairs.items():
        if name not in response:
            raise OptionError(f"margin for {name!r}: not a response feature "
                              f"(response features: {list(response)})")
        if isinstance(value, bool) or not isinstance(value, int | float) \
                or not np.isfinite(value) or value <= 0:
            raise OptionError(f"margin for {name!r} must be a number > 0, got {value!r}")
        out.append((name, float(value)))
    return tuple(out)


def response_effects(data: Transitions, design: Design, replicates: int, alpha: float,
                     level: float, margins: tuple[tuple[str, float], ...],
                     units: Mapping[str, str], rng: np.random.Generator,
                     assignments: np.ndarray | None = None) -> EffectSummary:
    """Response deviations with cluster-bootstrap intervals, equivalence, detectable effect and,
    given the design's ``assignments`` (row 0 observed), the deviation's permutation p-value."""
    moments = np.hstack([np.ones((len(data.residual), 1)), data.residual, data.residual**2])
    sums = unit_sums(data, moments, design.n_units)
    width = moments.shape[1]
    in_a = design.observed.astype(np.float64)
    observed = _side_sums(sums.matrix, np.ones((design.n_units, 1)), in_a, width)
    keep = (observed[:, 0, 0] >= MIN_TRANSITIONS).all(axis=-1)
    boot = _side_sums(sums.matrix, design.resamples(replicates, rng), in_a, width)
    if not keep.any():  # nothing to estimate from: say so, never "no deviation"
        return EffectSummary(level, replicates, 0, tuple(
            _not_estimable(name, units.get(name, ""), dict(margins).get(name))
            for name in data.response), False if margins else None)
    estimate, shift = _effects(observed[keep])
    boot_estimate, boot_shift = _effects(boot[keep])
    features = _feature_effects(data.response, estimate[:, 0], shift[:, 0], boot_estimate,
                                boot_shift, alpha, level, dict(margins), units)
    if assignments is not None:
        null = _effects(_assigned_sums(sums.matrix, assignments, width)[keep])[0]
        pvalues = exceedance_pvalues(null.T, null[:, 0])
        features = tuple(replace(f, pvalue=float(p)) for f, p in zip(features, pvalues,
                                                                     strict=True))
    verdicts = [f.equivalent for f in features if f.equivalent is not None]
    return EffectSummary(level, replicates, int(keep.sum()), features,
                         all(verdicts) if verdicts else None)


def _not_estimable(name: str, unit: str, margin: float | None) -> FeatureEffect:
    """No state has ``MIN_TRANSITIONS`` on both sides: every number is NaN (null in JSON) and a
    margin is not shown to hold."""
    nan = float("nan")
    return FeatureEffect(name, unit, nan, nan, nan, nan, nan, nan, nan, nan, nan, margin,
                         None if margin is None else False)


def _side_sums(matrix, weights: np.ndarray, in_a: np.ndarray, width: int) -> np.ndarray:
    """(blocks, width, k, 2) sums of the unit matrix over A's and B's units, each unit counted
    ``weights[unit, r]`` times in replicate ``r``. ``in_a``: A's units first (the design's
    order), so each side is one slice of the matrix's columns."""
    units_a = int(in_a.sum())
    if not in_a[:units_a].all():  # not the design's order: weight the whole matrix per side
        sides = [np.asarray(matrix @ (weights * side[:, None])) for side in (in_a, 1 - in_a)]
    else:
        matrix = sp.csr_matrix(matrix)
        sides = [np.asarray(matrix[:, cols] @ weights[cols])
                 for cols in (slice(0, units_a), slice(units_a, None))]
    return np.stack(sides, axis=-1).reshape(-1, width, weights.shape[1], 2)


def _assigned_sums(matrix, assignments: np.ndarray, width: int) -> np.ndarray:
    """(blocks, width, P + 1, 2) sums of the unit matrix over each assignment's A and B units."""
    side_a = assignments.T.astype(np.float64)  # (units, P + 1)
    sides = [np.asarray(matrix @ side) for side in (side_a, 1.0 - side_a)]
    return np.stack(sides, axis=-1).reshape(-1, width, assignments.shape[0], 2)


def _effects(sums: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Deviation and shift per feature and replicate from (states, width, reps, 2) side sums."""
    count = sums[:, 0]  # (states, reps, 2)
    j = (sums.shape[1] - 1) // 2
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = sums[:, 1:1 + j] / count[:, None]
        sd = np.sqrt(np.maximum(sums[:, 1 + j:] / count[:, None] - mean**2, 0.0))
    usable = (count >= 2).all(axis=-1)  # (states, reps)
    share = np.where(usable, count.sum(axis=-1), 0.0)
    share = share / np.maximum(share.sum(axis=0), 1.0)
    delta_mean = np.nan_to_num(mean[..., 0] - mean[..., 1])
    delta_sd = np.nan_to_num(sd[..., 0] - sd[..., 1])
    squared = (share[:, None] * (delta_mean**2 + delta_sd**2)).sum(axis=0)
    shift = (share[:, None] * delta_mean).sum(axis=0)
    return np.sqrt(squared), shift  # (features, reps)


def _feature_effects(names, estimate, shift, boot_estimate, boot_shift, alpha, level,
                     margins, units) -> tuple[FeatureEffect, ...]:
    tail = (1 - level) / 2
    z = norm.ppf(1 - alpha / 2) + norm.ppf(POWER)
    out = []
    for j, name in enumerate(names):
        q_lo, q_hi = np.quantile(boot_estimate[j], [tail, 1 - tail])
        s_lo, s_hi = np.quantile(boot_shift[j], [tail, 1 - tail])
        replicates = np.sort(boot_estimate[j])
        margin = margins.get(name)
        corrected = max(2 * estimate[j] - boot_estimate[j].mean(), 0.0)
        effect = FeatureEffect(
            name, units.get(name, ""), float(corrected), float(estimate[j]),
            float(max(2 * estimate[j] - q_hi, 0.0)), float(max(2 * estimate[j] - q_lo, 0.0)),
            float("nan"), float(shift[j]),
            float(2 * shift[j] - s_hi), float(2 * shift[j] - s_lo),
            float(z * boot_shift[j].std(ddof=1)) if boot_shift.shape[1] > 1 else float("nan"),
            margin, None, replicates=replicates)
        lower, upper = effect.bounds(alpha)
        out.append(replace(effect, upper=upper, lower=lower,
                           equivalent=None if margin is None else bool(upper < margin)))
    return tuple(out)
