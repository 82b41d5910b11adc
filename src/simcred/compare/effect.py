"""How large is the difference of the response law, with an interval, and is it small enough?

**Effect.** Per response feature ``j`` (in its unit per second, e.g. m/s² for a speed), the
*response deviation*

    E_j = √θ_j,   θ_j = Σ_s w_s [ (μ_A,s − μ_B,s)² + (σ_A,s − σ_B,s)² ]

over the states ``s`` that hold at least ``MIN_SHARE`` (0.5 %) of EACH side's transitions,
``w_s`` the average of the two sides' shares of ``s`` (renormalised over those states),
``μ``/``σ`` the mean and standard deviation in that state of the response after the global
covariate fit (:attr:`~simcred.compare.transitions.Transitions.effect_residual`: a state's own
fit would absorb part of the A–B difference, more as more states get one). Per state the
bracket is the squared 2-Wasserstein distance of the two normal laws with those moments: a bias,
a delay (a shifted conditional mean), a gain or a variance change all enter, in the feature's
own unit. The state
set and the weights are defined by shares of the two response laws, not by counts, so ``E`` is
one property of the two laws whatever the number or length of the runs (the paper's distance, a
count of rejected tests, grows with them). A state must also be visited by ``MIN_UNITS`` (2)
units of each side: its variances are estimated between units. ``shift_j = Σ_s w_s (μ_A,s −
μ_B,s)`` is the signed average bias.

**Estimate.** The plug-in ``θ̂`` is biased up: a squared difference of two estimates carries
their variance, ``E[(μ̂_A − μ̂_B)²] = (μ_A − μ_B)² + Var(μ̂_A − μ̂_B)``, and with a few
transitions per state that variance is larger than the deviation itself. The estimate removes
it per state and per moment [1]: ``θ̃ = Σ_s w_s [(Δμ̂² − V̂_μ) + (Δσ̂² − V̂_σ)]`` with cluster
(between-unit) variances of the linearised mean and standard deviation [2] — pairs resampled
together, so the members' covariance is subtracted — each with the leverage correction
``1/(1 − Σ_c N_c²/N²)`` of a cluster-robust variance with few clusters [3]. ``estimate =
√max(θ̃, 0)``; ``squared`` is ``θ̃`` itself (it can be negative); ``plugin = √θ̂``.

**Interval.** Cluster bootstrap over the design's units (runs or groups within each side, whole
pairs) [4], [5], with the state set fixed, of the bias-corrected ``θ̃*``, around the plug-in
``θ̂`` (the bootstrap world's true value); bounds as deviations (roots, clamped at 0). The upper
bound is the basic bound of the squared deviation, ``θ̃ − (q_{a/2}(θ̃*) − θ̂)``: where the
deviation is within the noise (where equivalence is decided) ``θ̃`` has the right-skewed law of a
sum of noncentral χ² terms, and the basic bound carries that tail. The lower bound is the basic
bound on the stabilised scale ``φ = √(θ + c)``, ``c = 2ν̂``, ``ν̂ = θ̂ − θ̃`` the estimated
noise: ``φ̃ − (q_{1−a/2}(φ*) − φ̂)``, back to ``θ`` as ``φ² − c`` (a sum of noncentral χ²
terms with variance ``≈ 4θν + 2ν²`` is stabilised by ``√(θ + ν/2)``; the larger offset ``2ν̂``
was chosen among 0.5–4 on the known-truth designs, calibration.md). Well above the noise
``φ`` is the deviation itself, whose law is near normal (the squared scale's skew would put the
lower bound far too low, "beyond the margin" would lose its power); within the noise it is
nearly the squared scale. The shift's interval is the basic bootstrap interval of its
replicates, each with the global fit refitted to first order (the fit's influence on the shift,
:mod:`simcred.compare.fit_influence`: holding the sample's fit fixed made the clip design's
bootstrap 1.12–1.21× its sampling spread). In a replicate a state enters ``θ̃*`` where at
least ``MIN_UNITS`` drawn units of each side visit it (its variances need two) and the shift
where at least one does: dropping from the shift the states a replicate happens to draw one
unit of made its bootstrap spread 1.3× its sampling spread (coverage 95.5–97 % at 90 %,
calibration.md).

**Power constraint** [9]. An upper bound is never below ``floor``, the deviation that the
permutation test of any deviation (``pvalue`` below) detects with 50 % power (``FLOOR_POWER``)
at the bound's level to first order, ``√(q_{1−a}(θ̂⁰) − q_{0.5}(θ̂⁰))`` from the plug-in's
permutation null ``θ̂⁰`` (the plug-in under a deviation ``θ`` read as ``θ`` plus a draw of that
null). Without it a draw whose noise happens to cancel a deviation puts the bound below
deviations the data cannot see: with 20 car-following episodes a 0.5 s reaction delay (deviation
0.055 m/s²) had a bound below 0.05 in 1 of 1,000 draws, with the floor in none. The floor only
raises bounds, so equivalence keeps its level and coverage can only grow. The first-order
reading overstates the test's power: at 40 pairs, where the delay's deviation is near the median
floor, the test detects it in 17 %, not 50 % (calibration.md, with what the floor costs in
power to show equivalence). 50 %, Cowan et al.'s median choice, was fixed before measuring.

**Equivalence** [6], [7], [8]. H0: ``E_j ≥ δ_j`` for some declared margin; H1: ``E_j < δ_j``
for all. Rejected (equivalence shown) when every one-sided upper ``1 − α`` bound
``max(√(θ̃ − (q_α(θ̃*) − θ̂)), floor)`` lies below its margin: an intersection–union test,
level α without adjustment. Little data gives wide bounds and "not shown equivalent", never
"equivalent".

**Is there any deviation?** ``pvalue``: the permutation p-value of the plug-in ``θ̂`` under
the design's assignments (the states that enter fixed): exact when the two response laws are the
same, whatever the sample size, and sensitive to changes of sign between states (an RMS, unlike a
pooled mean). A caller that declares "beyond the margin" can require it besides the bootstrap
lower bound, so that a candidate with the reference's own law is never declared beyond at more
than the test's level, however few units there are.

**Detectable effect.** ``mde_j = (z_{1−α/2} + z_{0.8}) · se(shift_j)``: the uniform shift of the
response that a test of the mean response would detect with 80 % power, with the bootstrap
standard error of ``shift_j`` (a normal approximation).

References
----------
[1] Cochran, Sampling Techniques, 3rd ed., Wiley, 1977 (sec. 6.9: variance of a ratio
    estimate); the squared difference less its variance is the unbiased estimate of a squared
    contrast (e.g. the numerator of a random-effects variance, Searle, Casella & McCulloch,
    Variance Components, Wiley, 1992, ch. 3).
[2] Cameron & Miller, A practitioner's guide to cluster-robust inference, J. Human Resources 50,
    2015.
[3] Bell & McCaffrey, Bias reduction in standard errors for linear regression with multi-stage
    samples, Survey Methodology 28, 2002 (CR2).
[4] Field & Welsh, Bootstrapping clustered data, JRSS B 69, 2007.
[5] Davison & Hinkley, Bootstrap Methods and their Application, CUP, 1997 (sec. 3.8, 5.2).
[6] Schuirmann, A comparison of the two one-sided tests procedure..., J. Pharmacokin. Biopharm.
    15, 1987.
[7] Wellek, Testing Statistical Hypotheses of Equivalence and Noninferiority, 2nd ed., CRC, 2010.
[8] Robinson & Froese, Model validation using equivalence tests, Ecol. Modelling 176, 2004.
[9] Cowan, Cranmer, Gross & Vitells, Power-constrained limits, arXiv:1105.3166, 2011.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import norm

from simcred.compare.cluster_sums import MIN_SHARE, MIN_UNITS, ClusterSums, Entries, normalised
from simcred.compare.design import Design
from simcred.compare.fit_influence import shift_fit_influence
from simcred.compare.runs import exceedance_pvalues
from simcred.compare.side_counts import is_paired
from simcred.compare.threads import in_threads
from simcred.compare.transitions import Transitions
from simcred.compare.unit_sums import side_sums, unit_matrix
from simcred.errors import OptionError

#: The entry rule in words (warnings, docs).
ENTRY = (f"holds {100 * MIN_SHARE:g} % of each side's transitions and is visited by "
         f"{MIN_UNITS} units of each side")
#: Offset of the lower bound's stabilised scale, in units of the estimated noise θ̂ − θ̃ (module
#: docs; chosen among 0.5–4 on the known-truth designs, calibration.md).
STABILISER = 2.0
POWER = 0.8
#: Power at which the upper bounds' floor is detected (module docs: "Power constraint").
FLOOR_POWER = 0.5
#: Units per state below which a state's noise has no unbiased variance estimate: the width
#: needs fourth-degree moments, estimable from four units (calibration.md, "Session 30").
FEW_UNITS = 4


@dataclass(frozen=True, slots=True)
class FeatureEffect:
    """The response deviation of one feature, its interval and what the data could detect.

    ``estimate``: bias-corrected ``√max(θ̃, 0)``; ``plugin``: ``√θ̂``; ``squared``: ``θ̃`` (the
    bias-corrected squared deviation, negative when the noise exceeds the signal);
    ``low``/``high``: bootstrap interval (:meth:`bounds` at ``(1 − level)/2``);
    ``upper``/``lower``: one-sided ``1 − α`` bounds (``upper`` is the equivalence test's);
    ``shift``: signed mean bias with its interval; ``mde``: detectable uniform shift;
    ``pvalue``: permutation p-value of any deviation; ``floor``: the upper bounds' floor at α,
    the deviation that test detects with 50 % power to first order (``null``: its permutation null
    of ``θ̂``, sorted, not written to JSON). ``replicates``: the bootstrap replicates
    ``θ̃*`` in the feature's unit, as signed roots ``sign(θ̃*)·√|θ̃*|`` (not written to JSON),
    from which :meth:`bounds` gives one-sided bounds at any other level.
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
    squared: float = float("nan")
    replicates: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False,
                                   compare=False)
    shift_replicates: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False,
                                         compare=False)
    floor: float = float("nan")
    null: np.ndarray = field(default_factory=lambda: np.empty(0), repr=False, compare=False)

    def bounds(self, alpha: float) -> tuple[float, float]:
        """One-sided ``1 − alpha`` lower and upper bounds, as deviations (clamped at 0); NaN
        when not estimable. Module docs: the upper bound is the basic bootstrap bound of the
        squared deviation, never below :meth:`power_floor`; the lower bound the basic bound on
        the stabilised scale ``√(θ + c)``, ``c = STABILISER · (θ̂ − θ̃)``."""
        if len(self.replicates) == 0 or not np.isfinite(self.squared):
            return float("nan"), float("nan")
        plugin, squared = self.plugin**2, self.squared
        replicates = np.sign(self.replicates) * self.replicates**2
        upper = max(squared - (np.quantile(replicates, alpha) - plugin), self.power_floor(alpha))
        c = STABILISER * max(plugin - squared, 0.0)
        stable = np.sqrt(np.maximum(replicates + c, 0.0))
        lower = max(np.sqrt(max(squared + c, 0.0))
                    - (np.quantile(stable, 1 - alpha) - np.sqrt(plugin + c)), 0.0)**2 - c
        return float(np.sqrt(max(lower, 0.0))), float(np.sqrt(max(upper, 0.0)))

    def power_floor(self, alpha: float) -> float:
        """The squared deviation that the permutation test of any deviation at level
        ``alpha`` detects with :data:`FLOOR_POWER` power, to first order: ``q_{1−alpha} −
        q_{1−FLOOR_POWER}`` of the plug-in's permutation null (module docs); 0 without one."""
        if len(self.null) < 2:
            return 0.0
        high, centre = np.quantile(self.null, [1 - alpha, 1 - FLOOR_POWER])
        return float(max(high - centre, 0.0))

    def shift_bounds(self, alpha: float) -> tuple[float, float]:
        """One-sided ``1 − alpha`` lower and upper bounds of ``shift``: basic bootstrap bounds
        ``2 shift − q_{1−alpha}``, ``2 shift − q_alpha`` of its replicates; NaN without."""
        if len(self.shift_replicates) == 0 or not np.isfinite(self.shift):
            return float("nan"), float("nan")
        high, low = np.quantile(self.shift_replicates, [alpha, 1 - alpha])
        return float(2 * self.shift - low), float(2 * self.shift - high)


@dataclass(frozen=True, slots=True)
class EffectSummary:
    """Effects of all response features; ``equivalent``: every margin met (None: no margin).
    ``states``: how many states entered (0: not estimable, every estimate NaN);
    ``units_per_state``: the units those states rest on (:meth:`Entries.fewest_units`; below
    :data:`FEW_UNITS` the interval's width and the standard deviations' bias correction depend
    on tails that so few units cannot estimate)."""

    level: float
    replicates: int
    states: int
    features: tuple[FeatureEffect, ...]
    equivalent: bool | None
    units_per_state: float = float("nan")


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


@dataclass(frozen=True, slots=True, eq=False)
class EffectNull:
    """The effect's states and the plug-in deviation of every assignment (None: no
    assignments, or no state enters): what :func:`response_effects` needs from the design's
    assignments, computable beside the response test."""

    entries: Entries
    keep: np.ndarray
    null: np.ndarray | None


def effect_null(data: Transitions, design: Design, assignments: np.ndarray | None
                ) -> EffectNull:
    """The entering states and, given ``assignments`` (row 0 observed), the plug-in squared
    deviation of every assignment (features, P + 1)."""
    entries = Entries.of(data, design)
    keep = entries.entering()
    null = None if assignments is None or not keep.any() \
        else _permuted_plugin(entries, keep, assignments)
    return EffectNull(entries, keep, null)


def response_effects(data: Transitions, design: Design, replicates: int, alpha: float,
                     level: float, margins: tuple[tuple[str, float], ...],
                     units: Mapping[str, str], rng: np.random.Generator,
                     assignments: np.ndarray | None = None,
                     prepared: EffectNull | None = None) -> EffectSummary:
    """Response deviations with cluster-bootstrap intervals, equivalence, detectable effect and,
    given the design's ``assignments`` (row 0 observed), the deviation's permutation p-value
    (``prepared``: :func:`effect_null` of the same arguments, computed already)."""
    found = prepared if prepared is not None else effect_null(data, design, assignments)
    entries, keep = found.entries, found.keep
    weights = design.resamples(replicates, rng)
    if not keep.any():  # nothing to estimate from: say so, never "no deviation"
        return EffectSummary(level, replicates, 0, tuple(
            _not_estimable(name, units.get(name, ""), dict(margins).get(name))
            for name in data.response), False if margins else None)
    sums = ClusterSums.of(entries, keep)
    if entries.pairs:
        weights = weights[:design.units_a]  # a pair's members are drawn together
    every = sums.deviation(np.hstack([np.ones((len(weights), 1)), weights]))  # observed first
    influence = shift_fit_influence(data, entries, keep)
    if influence is not None:  # each replicate refitted (fit_influence.py)
        every["shift"][:, 1:] -= influence.T @ weights
    observed = {name: value[:, :1] for name, value in every.items()}
    boot = {name: value[:, 1:] for name, value in every.items()}
    features = _feature_effects(data.response, observed, boot, found.null, alpha, level,
                                dict(margins), units)
    verdicts = [f.equivalent for f in features if f.equivalent is not None]
    return EffectSummary(level, replicates, int(keep.sum()), features,
                         all(verdicts) if verdicts else None, entries.fewest_units(keep))


def _not_estimable(name: str, unit: str, margin: float | None) -> FeatureEffect:
    """No state enters (:data:`ENTRY`): every number is NaN (null in JSON) and a margin is not
    shown to hold."""
    nan = float("nan")
    return FeatureEffect(name, unit, nan, nan, nan, nan, nan, nan, nan, nan, nan, margin,
                         None if margin is None else False)


def _permuted_plugin(entries: Entries, keep: np.ndarray, assignments: np.ndarray
                     ) -> np.ndarray:
    """(features, P + 1) plug-in squared deviation of every assignment (states fixed); the
    batches in threads (each its own columns)."""
    j = entries.first.shape[1]
    out = np.zeros((j, assignments.shape[0]))
    sides = AssignmentSides(entries, keep, assignments)

    def one_batch(start: int) -> None:
        side, total = sides.batch(start)
        out[:, start:start + len(total[0])] = _plugin(side, total, j)

    in_threads(one_batch, sides.starts)
    return out


def assignment_sides(entries: Entries, keep: np.ndarray, assignments: np.ndarray
                     ) -> Iterator[tuple[int, list, list]]:
    """:meth:`AssignmentSides.batch` of every batch, in order, with the index of its first row."""
    sides = AssignmentSides(entries, keep, assignments)
    for start in sides.starts:
        yield start, *sides.batch(start)


class AssignmentSides:
    """Each side's sums of the entering states ``keep`` under batches of assignments."""

    BATCH = 256

    def __init__(self, entries: Entries, keep: np.ndarray, assignments: np.ndarray) -> None:
        take = keep[entries.state]
        state = (np.cumsum(keep) - 1)[entries.state[take]]
        unit = entries.unit[take]
        n_states, n_units = int(keep.sum()), assignments.shape[1]
        values = np.hstack([entries.count[take, None], entries.first[take],
                            entries.second[take]])
        self.width, self.n_states = values.shape[1], n_states
        matrix = unit_matrix([(unit, state, values)], n_units, n_states)
        self.totals = np.bincount(entries.unit, weights=entries.count, minlength=n_units)
        self.pooled = np.asarray(matrix.sum(axis=1)).reshape(self.width, n_states, 1)
        self.product = side_sums(matrix, is_paired(assignments))
        self.assignments = assignments
        self.starts = range(0, assignments.shape[0], self.BATCH)

    def batch(self, start: int) -> tuple[list, list]:
        """Each side's (1 + 2J, states, k) sums (count, then the sums of the residual and of its
        square) and each side's transitions (k,) for the assignments from row ``start``."""
        rows = self.assignments[start:start + self.BATCH]
        a = self.product(rows).reshape(self.width, self.n_states, -1)
        total_a = rows @ self.totals
        return [a, self.pooled - a], [total_a, self.totals.sum() - total_a]


def plugin_terms(sides, total, j: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The plug-in's state weights (states, k) and squared differences of the means and of the
    standard deviations (each features, states, k) from per-side (1 + 2J, states, k) sums (a
    state with fewer than 2 transitions on a side has weight 0)."""
    count = [s[0] for s in sides]
    usable = (count[0] >= 2) & (count[1] >= 2)
    w = normalised(np.where(usable, 0.5 * (count[0] / total[0] + count[1] / total[1]), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = [s[1:1 + j] / c for s, c in zip(sides, count, strict=True)]
        sd = [np.sqrt(np.maximum(s[1 + j:] / c - m**2, 0.0))
              for s, c, m in zip(sides, count, mean, strict=True)]
    return w, np.nan_to_num((mean[0] - mean[1])**2), np.nan_to_num((sd[0] - sd[1])**2)


def _plugin(sides, total, j: int) -> np.ndarray:
    """(features, assignments) plug-in squared deviation (:func:`plugin_terms`)."""
    w, mean_part, sd_part = plugin_terms(sides, total, j)
    return (w * (mean_part + sd_part)).sum(axis=1)


def _signed_root(x: np.ndarray) -> np.ndarray:
    return np.sign(x) * np.sqrt(np.abs(x))


def _feature_effects(names, observed, boot, null, alpha, level, margins, units
                     ) -> tuple[FeatureEffect, ...]:
    """Each feature's effect; given the plug-in's permutation ``null`` (features, P + 1;
    column 0 observed) also its p-value and the bounds' power floor."""
    tail = (1 - level) / 2
    z = norm.ppf(1 - alpha / 2) + norm.ppf(POWER)
    pvalues = [float("nan")] * len(names) if null is None \
        else exceedance_pvalues(null.T, null[:, 0])
    out = []
    for j, name in enumerate(names):
        plugin, squared = observed["plugin"][j, 0], observed["squared"][j, 0]
        shift, boot_shift = observed["shift"][j, 0], boot["shift"][j]
        margin = margins.get(name)
        effect = FeatureEffect(
            name, units.get(name, ""), float(np.sqrt(max(squared, 0.0))),
            float(np.sqrt(plugin)), float("nan"), float("nan"), float("nan"), float(shift),
            float("nan"), float("nan"),
            float(z * boot_shift.std(ddof=1)) if len(boot_shift) > 1 else float("nan"),
            margin, None, squared=float(squared),
            replicates=np.sort(_signed_root(boot["squared"][j])),
            shift_replicates=np.sort(boot_shift), pvalue=float(pvalues[j]),
            null=np.empty(0) if null is None else np.sort(null[j, 1:]))
        if null is not None:
            effect = replace(effect, floor=float(np.sqrt(effect.power_floor(alpha))))
        low, high = effect.bounds(tail)
        lower, upper = effect.bounds(alpha)
        shift_low, shift_high = effect.shift_bounds(tail)
        out.append(replace(effect, low=low, high=high, upper=upper, lower=lower,
                           shift_low=shift_low, shift_high=shift_high,
                           equivalent=None if margin is None else bool(upper < margin)))
    return tuple(out)
