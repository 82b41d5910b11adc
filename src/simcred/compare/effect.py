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
nearly the squared scale.

**Equivalence** [6], [7], [8]. H0: ``E_j ≥ δ_j`` for some declared margin; H1: ``E_j < δ_j``
for all. Rejected (equivalence shown) when every one-sided upper ``1 − α`` bound
``√(θ̃ − (q_α(θ̃*) − θ̂))`` lies below its margin: an intersection–union test, level α without
adjustment. Little data gives wide bounds and "not shown equivalent", never "equivalent".

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
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from scipy.stats import norm

from simcred.compare.design import Design, DesignKind
from simcred.compare.runs import exceedance_pvalues
from simcred.compare.transitions import Transitions
from simcred.compare.unit_sums import unique_inverse, unit_matrix
from simcred.errors import OptionError

#: A state enters the effect when it holds at least this share of EACH side's transitions ...
MIN_SHARE = 0.005
#: ... and at least this many units of each side visit it (its variances are estimated between
#: units, which needs two).
MIN_UNITS = 2
#: The entry rule in words (warnings, docs).
ENTRY = (f"holds {100 * MIN_SHARE:g} % of each side's transitions and is visited by "
         f"{MIN_UNITS} units of each side")
#: Offset of the lower bound's stabilised scale, in units of the estimated noise θ̂ − θ̃ (module
#: docs; chosen among 0.5–4 on the known-truth designs, calibration.md).
STABILISER = 2.0
POWER = 0.8
_CHUNK = 64  # bootstrap replicates evaluated at once


@dataclass(frozen=True, slots=True)
class FeatureEffect:
    """The response deviation of one feature, its interval and what the data could detect.

    ``estimate``: bias-corrected ``√max(θ̃, 0)``; ``plugin``: ``√θ̂``; ``squared``: ``θ̃`` (the
    bias-corrected squared deviation, negative when the noise exceeds the signal);
    ``low``/``high``: bootstrap interval (:meth:`bounds` at ``(1 − level)/2``);
    ``upper``/``lower``: one-sided ``1 − α`` bounds (``upper`` is the equivalence test's);
    ``shift``: signed mean bias with its interval; ``mde``: detectable uniform shift;
    ``pvalue``: permutation p-value of any deviation. ``replicates``: the bootstrap replicates
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

    def bounds(self, alpha: float) -> tuple[float, float]:
        """One-sided ``1 − alpha`` lower and upper bounds, as deviations (clamped at 0); NaN
        when not estimable. Module docs: the upper bound is the basic bootstrap bound of the
        squared deviation, the lower bound the basic bound on the stabilised scale
        ``√(θ + c)``, ``c = STABILISER · (θ̂ − θ̃)``."""
        if len(self.replicates) == 0 or not np.isfinite(self.squared):
            return float("nan"), float("nan")
        plugin, squared = self.plugin**2, self.squared
        replicates = np.sign(self.replicates) * self.replicates**2
        upper = squared - (np.quantile(replicates, alpha) - plugin)
        c = STABILISER * max(plugin - squared, 0.0)
        stable = np.sqrt(np.maximum(replicates + c, 0.0))
        lower = max(np.sqrt(max(squared + c, 0.0))
                    - (np.quantile(stable, 1 - alpha) - np.sqrt(plugin + c)), 0.0)**2 - c
        return float(np.sqrt(max(lower, 0.0))), float(np.sqrt(max(upper, 0.0)))


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
    entries = _Entries.of(data, design)
    keep = entries.entering()
    weights = design.resamples(replicates, rng)
    if not keep.any():  # nothing to estimate from: say so, never "no deviation"
        return EffectSummary(level, replicates, 0, tuple(
            _not_estimable(name, units.get(name, ""), dict(margins).get(name))
            for name in data.response), False if margins else None)
    sums = _Sums.of(entries, keep)
    if entries.pairs:
        weights = weights[:design.units_a]  # a pair's members are drawn together
    observed = sums.deviation(np.ones((sums.totals.shape[0], 1)))
    boot = [sums.deviation(weights[:, i:i + _CHUNK])
            for i in range(0, weights.shape[1], _CHUNK)]
    boot = {name: np.hstack([b[name] for b in boot]) for name in observed}
    features = _feature_effects(data.response, observed, boot, alpha, level, dict(margins),
                                units)
    if assignments is not None:
        null = _permuted_plugin(entries, keep, assignments)
        pvalues = exceedance_pvalues(null.T, null[:, 0])
        features = tuple(replace(f, pvalue=float(p)) for f, p in zip(features, pvalues,
                                                                     strict=True))
    verdicts = [f.equivalent for f in features if f.equivalent is not None]
    return EffectSummary(level, replicates, int(keep.sum()), features,
                         all(verdicts) if verdicts else None)


def _not_estimable(name: str, unit: str, margin: float | None) -> FeatureEffect:
    """No state enters (:data:`ENTRY`): every number is NaN (null in JSON) and a margin is not
    shown to hold."""
    nan = float("nan")
    return FeatureEffect(name, unit, nan, nan, nan, nan, nan, nan, nan, nan, nan, margin,
                         None if margin is None else False)


def _permuted_plugin(entries: _Entries, keep: np.ndarray, assignments: np.ndarray
                     ) -> np.ndarray:
    """(features, P + 1) plug-in squared deviation of every assignment (states fixed)."""
    take = keep[entries.state]
    state = (np.cumsum(keep) - 1)[entries.state[take]]
    unit = entries.unit[take]
    n_states, n_units = int(keep.sum()), assignments.shape[1]
    j = entries.first.shape[1]
    values = np.hstack([entries.count[take, None], entries.first[take], entries.second[take]])
    width = values.shape[1]
    matrix = unit_matrix(unit, state, values.__getitem__, width, n_units, n_states)
    totals = np.bincount(entries.unit, weights=entries.count, minlength=n_units)
    pooled = np.asarray(matrix.sum(axis=1)).reshape(n_states, width, 1)
    side_a = assignments.T.astype(np.float64)  # (units, P + 1)
    out = np.zeros((j, assignments.shape[0]))
    for start in range(0, side_a.shape[1], 256):
        cols = side_a[:, start:start + 256]
        a = np.asarray(matrix @ cols).reshape(n_states, width, -1)
        total_a = totals @ cols
        out[:, start:start + 256] = _plugin([a, pooled - a], [total_a, totals.sum() - total_a], j)
    return out


def _plugin(sides, total, j: int) -> np.ndarray:
    """(features, assignments) plug-in squared deviation from per-side (states, 1 + 2J, k) sums
    (a state with fewer than 2 transitions on a side drops out)."""
    count = [s[:, 0] for s in sides]
    usable = (count[0] >= 2) & (count[1] >= 2)
    share = np.where(usable, 0.5 * (count[0] / total[0] + count[1] / total[1]), 0.0)
    w = share / np.where(share.sum(axis=0) > 0, share.sum(axis=0), 1.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = [s[:, 1:1 + j] / c[:, None] for s, c in zip(sides, count, strict=True)]
        sd = [np.sqrt(np.maximum(s[:, 1 + j:] / c[:, None] - m**2, 0.0))
              for s, c, m in zip(sides, count, mean, strict=True)]
    squared = np.nan_to_num((mean[0] - mean[1])**2 + (sd[0] - sd[1])**2)
    return (w[:, None] * squared).sum(axis=0)


@dataclass(frozen=True, slots=True, eq=False)
class _Entries:
    """Sums per (state, unit) of the pooled transitions: ``state`` indexes the distinct states,
    ``side`` 0 (A) / 1 (B), ``cluster`` the resampled unit (the pair for a paired design)."""

    state: np.ndarray
    unit: np.ndarray
    side: np.ndarray
    cluster: np.ndarray
    count: np.ndarray  # (entries,)
    first: np.ndarray  # (entries, J) sums of the residual
    second: np.ndarray  # (entries, J) sums of its square
    n_states: int
    n_clusters: int
    pairs: bool

    @classmethod
    def of(cls, data: Transitions, design: Design) -> _Entries:
        state, unit, x = data.state, data.unit, data.effect_residual
        new = np.r_[True, (state[1:] != state[:-1]) | (unit[1:] != unit[:-1])]
        starts = np.flatnonzero(new)
        codes, index = np.unique(state[starts], return_inverse=True)
        units = unit[starts]
        pairs = design.kind is DesignKind.PAIRS
        side = (units >= design.units_a).astype(np.int64)
        return cls(index, units, side, units % design.units_a if pairs else units,
                   np.diff(np.r_[starts, len(state)]).astype(np.float64),
                   np.add.reduceat(x, starts, axis=0), np.add.reduceat(x**2, starts, axis=0),
                   len(codes), design.units_a if pairs else design.n_units, pairs)

    def per_state(self, values: np.ndarray) -> np.ndarray:
        """(states, 2) sums of ``values`` per state and side."""
        out = np.zeros((self.n_states, 2))
        np.add.at(out, (self.state, self.side), values)
        return out

    def entering(self) -> np.ndarray:
        """The states that enter the effect (module docs: :data:`ENTRY`)."""
        count = self.per_state(self.count)
        share = count / np.maximum(count.sum(axis=0), 1.0)
        visits = self.per_state(np.ones(len(self.count)))
        return ((share >= MIN_SHARE) & (visits >= MIN_UNITS)).all(axis=1)

    def totals(self) -> np.ndarray:
        """(clusters, 2) transitions per cluster and side over all states."""
        out = np.zeros((self.n_clusters, 2))
        np.add.at(out, (self.cluster, self.side), self.count)
        return out


@dataclass(frozen=True, slots=True, eq=False)
class _Sums:
    """Per entering state and cluster: the sums and the products of sums the cluster variances
    need, as a sparse (states · width) × clusters matrix, so that any resampling weights of the
    clusters give every replicate's moments and variances with one product."""

    matrix: np.ndarray | sp.csc_matrix  # (states · width) × clusters
    visits: sp.csr_matrix  # (states · 2) × clusters: the cluster's side-k member visits
    totals: np.ndarray  # (clusters, 2)
    column: dict
    n_states: int
    features: int
    pairs: bool

    @classmethod
    def of(cls, entries: _Entries, keep: np.ndarray) -> _Sums:
        new_index = np.cumsum(keep) - 1
        take = keep[entries.state]
        state = new_index[entries.state[take]]
        side, cluster = entries.side[take], entries.cluster[take]
        n_states, n_clusters = int(keep.sum()), entries.n_clusters
        j = entries.first.shape[1]
        key, inverse = unique_inverse(cluster * n_states + state)
        x = np.zeros((len(key), 2, 1 + 2 * j))  # per (state, cluster) and side: N, S1, S2
        x[inverse, side] = np.hstack([entries.count[take, None], entries.first[take],
                                      entries.second[take]])  # (state, unit) occurs once
        spec = _product_spec(j, entries.pairs)
        column = {name: i for i, (name, _, _) in enumerate(spec)}
        matrix = unit_matrix(key // n_states, key % n_states,
                             lambda part: np.stack([_product(x[part], one, two)
                                                    for _, one, two in spec], axis=1),
                             len(spec), n_clusters, n_states)
        visits = sp.csr_matrix(
            (np.ones(int(take.sum())), (2 * state + side, cluster)),
            shape=(2 * n_states, n_clusters))
        return cls(matrix, visits, entries.totals(), column, n_states, j, entries.pairs)

    def deviation(self, weights: np.ndarray) -> dict[str, np.ndarray]:
        """(features, replicates) plug-in and bias-corrected squared deviations and shifts, each
        cluster counted ``weights[cluster, r]`` times in replicate ``r``."""
        r = weights.shape[1]
        q = np.asarray(self.matrix @ weights).reshape(self.n_states, -1, r)
        drawn = np.asarray(self.visits @ (weights > 0)).reshape(self.n_states, 2, r)
        total = self.totals.T @ weights  # (2, r)
        col = self.column

        def get(*name):
            return q[:, col[name]]

        count = [get("N", k) for k in (0, 1)]
        usable = (drawn >= MIN_UNITS).all(axis=1)
        share = np.where(usable, 0.5 * (count[0] / total[0] + count[1] / total[1]), 0.0)
        w = share / np.where(share.sum(axis=0) > 0, share.sum(axis=0), 1.0)
        out = {name: np.zeros((self.features, r)) for name in ("plugin", "squared", "shift")}
        with np.errstate(invalid="ignore", divide="ignore"):
            inflate = [1.0 / (1.0 - np.minimum(get("NN", k) / count[k]**2, 1.0))
                       for k in (0, 1)]  # leverage correction of the cluster variance
            for j in range(self.features):
                sides = [_side_moments(get, count[k], inflate[k], k, j) for k in (0, 1)]
                a, b = sides
                var_mean = a["var_mean"] + b["var_mean"]
                var_sd = a["var_sd"] + b["var_sd"]
                if self.pairs:  # the two members of a pair are resampled together
                    cov_mean, cov_var = _pair_covariances(get, count, inflate, a, b, j)
                    var_mean = var_mean - 2 * cov_mean
                    rho = np.clip(cov_var / np.sqrt(a["var_v"] * b["var_v"]), -1.0, 1.0)
                    var_sd = var_sd - 2 * np.nan_to_num(rho) * np.sqrt(a["var_sd"] * b["var_sd"])
                d_mean = np.where(usable, a["mean"] - b["mean"], 0.0)
                d_sd = np.where(usable, a["sd"] - b["sd"], 0.0)
                plugin = d_mean**2 + d_sd**2
                noise = np.where(usable, np.maximum(var_mean, 0.0) + np.maximum(var_sd, 0.0),
                                 0.0)
                out["plugin"][j] = (w * plugin).sum(axis=0)
                out["squared"][j] = (w * (plugin - noise)).sum(axis=0)
                out["shift"][j] = (w * d_mean).sum(axis=0)
        return out


def _product_spec(j: int, pairs: bool) -> list[tuple[tuple, tuple[int, int],
                                                     tuple[int, int] | None]]:
    """The columns kept per (state, cluster) row, as (name, factor, factor or None) with a
    factor (side, sum) over N, S1 and S2 of each feature: the sums of each side, their products
    and, for pairs, the products of the two members' sums."""
    out: list = []
    for k in (0, 1):
        out += [(("N", k), (k, 0), None), (("NN", k), (k, 0), (k, 0))]
        for f in range(j):
            s1, s2 = (k, 1 + f), (k, 1 + j + f)
            out += [(("S1", k, f), s1, None), (("S2", k, f), s2, None),
                    (("NS1", k, f), (k, 0), s1), (("NS2", k, f), (k, 0), s2),
                    (("S1S1", k, f), s1, s1), (("S1S2", k, f), s1, s2), (("S2S2", k, f), s2, s2)]
    if pairs:
        out.append((("NN", "AB"), (0, 0), (1, 0)))
        for f in range(j):
            parts = {"N": 0, "S1": 1 + f, "S2": 1 + j + f}
            out += [((p + s, "AB", f), (0, ip), (1, is_)) for p, ip in parts.items()
                    for s, is_ in parts.items() if p != "N" or s != "N"]
    return out


def _product(x: np.ndarray, one: tuple[int, int], two: tuple[int, int] | None) -> np.ndarray:
    return x[:, one[0], one[1]] if two is None else x[:, one[0], one[1]] * x[:, two[0], two[1]]


def _side_moments(get, n, inflate, k, j) -> dict[str, np.ndarray]:
    """Mean, standard deviation and their cluster variances of one side in every state."""
    mean = get("S1", k, j) / n
    var = np.maximum(get("S2", k, j) / n - mean**2, 0.0)
    nn, ns1, ns2 = get("NN", k), get("NS1", k, j), get("NS2", k, j)
    s11, s12, s22 = get("S1S1", k, j), get("S1S2", k, j), get("S2S2", k, j)
    # Σ_c w_c ψ_c² of the linearised mean (S1_c − μ N_c)/N and variance
    # (S2_c − 2μ S1_c + (μ² − v) N_c)/N, expanded in the clusters' sums and products
    a, b = -2 * mean, mean**2 - var
    var_mean = np.maximum(s11 - 2 * mean * ns1 + mean**2 * nn, 0.0) / n**2 * inflate
    var_v = np.maximum(s22 + a**2 * s11 + b**2 * nn + 2 * a * s12 + 2 * b * ns2
                       + 2 * a * b * ns1, 0.0) / n**2 * inflate
    var_sd = np.minimum(var_v / (4 * var), var)  # delta method, at most the variance itself
    return {"mean": mean, "sd": np.sqrt(var), "var_mean": var_mean, "var_v": var_v,
            "var_sd": np.nan_to_num(var_sd), "a": a, "b": b}


def _pair_covariances(get, n, inflate, a, b, j):
    """Σ_c w_c ψ_A,c ψ_B,c of the mean and the variance (the members of a pair together)."""
    scale = n[0] * n[1] / np.sqrt(inflate[0] * inflate[1])
    cov_mean = (get("S1S1", "AB", j) - b["mean"] * get("S1N", "AB", j)
                - a["mean"] * get("NS1", "AB", j) + a["mean"] * b["mean"] * get("NN", "AB"))
    cov_var = (get("S2S2", "AB", j) + b["a"] * get("S2S1", "AB", j)
               + b["b"] * get("S2N", "AB", j) + a["a"] * get("S1S2", "AB", j)
               + a["a"] * b["a"] * get("S1S1", "AB", j) + a["a"] * b["b"] * get("S1N", "AB", j)
               + a["b"] * get("NS2", "AB", j) + a["b"] * b["a"] * get("NS1", "AB", j)
               + a["b"] * b["b"] * get("NN", "AB"))
    return cov_mean / scale, cov_var / scale


def _signed_root(x: np.ndarray) -> np.ndarray:
    return np.sign(x) * np.sqrt(np.abs(x))


def _feature_effects(names, observed, boot, alpha, level, margins, units
                     ) -> tuple[FeatureEffect, ...]:
    tail = (1 - level) / 2
    z = norm.ppf(1 - alpha / 2) + norm.ppf(POWER)
    out = []
    for j, name in enumerate(names):
        plugin, squared = observed["plugin"][j, 0], observed["squared"][j, 0]
        shift, boot_shift = observed["shift"][j, 0], boot["shift"][j]
        s_lo, s_hi = np.quantile(boot_shift, [tail, 1 - tail])
        margin = margins.get(name)
        effect = FeatureEffect(
            name, units.get(name, ""), float(np.sqrt(max(squared, 0.0))),
            float(np.sqrt(plugin)), float("nan"), float("nan"), float("nan"), float(shift),
            float(2 * shift - s_hi), float(2 * shift - s_lo),
            float(z * boot_shift.std(ddof=1)) if len(boot_shift) > 1 else float("nan"),
            margin, None, squared=float(squared),
            replicates=np.sort(_signed_root(boot["squared"][j])))
        low, high = effect.bounds(tail)
        lower, upper = effect.bounds(alpha)
        out.append(replace(effect, low=low, high=high, upper=upper, lower=lower,
                           equivalent=None if margin is None else bool(upper < margin)))
    return tuple(out)
