"""The response effect's sums per (state, cluster): what every bootstrap replicate of the
deviation is computed from (:mod:`simcred.compare.effect` defines the estimand and the interval).

:class:`Entries` holds, per (state, unit) of the pooled transitions, the count and the sums of
the residual and of its square; :class:`ClusterSums` lays out, per entering state and cluster
(a unit, a group, or a pair: both members drawn together), those sums and the products of sums
that the cluster (between-unit) variances need, as one (width · states) × clusters matrix, so
that any resampling weights of the clusters give every replicate's moments, variances and
deviation with one product.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from simcred.compare.design import Design, DesignKind
from simcred.compare.threads import in_threads
from simcred.compare.transitions import Transitions
from simcred.compare.unit_sums import ProductColumns, unit_matrix

#: A state enters the effect when it holds at least this share of EACH side's transitions ...
MIN_SHARE = 0.005
#: ... and at least this many units of each side visit it (its variances are estimated between
#: units, which needs two).
MIN_UNITS = 2
#: Fill share from which the clusters' visits are a dense float32 array (4 bytes a position
#: against 12 a stored value; a dense product is ~10x faster than the sparse one per value).
VISITS_DENSE_SHARE = 1 / 3


@dataclass(frozen=True, slots=True, eq=False)
class Entries:
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
    def of(cls, data: Transitions, design: Design) -> Entries:
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
        return np.bincount(2 * self.state + self.side, weights=values,
                           minlength=2 * self.n_states).reshape(self.n_states, 2)

    def shares(self) -> np.ndarray:
        """(states, 2) each side's share of its transitions per state."""
        count = self.per_state(self.count)
        return count / np.maximum(count.sum(axis=0), 1.0)

    def visits(self) -> np.ndarray:
        """(states, 2) units of each side that visit each state."""
        return self.per_state(np.ones(len(self.count)))

    def entering(self) -> np.ndarray:
        """The states that enter the effect (module docs: :data:`ENTRY`)."""
        return ((self.shares() >= MIN_SHARE) & (self.visits() >= MIN_UNITS)).all(axis=1)

    def state_weights(self, keep: np.ndarray) -> np.ndarray:
        """The entering states' weights: the mean of the two sides' shares of their
        transitions, renormalised over ``keep``."""
        return normalised(self.shares().mean(axis=1)[keep])

    def fewest_units(self, keep: np.ndarray) -> float:
        """The units the entering states ``keep`` rest on: per state the units of the side with
        fewer, averaged with :meth:`state_weights`; NaN where none enters."""
        if not keep.any():
            return float("nan")
        return float((self.state_weights(keep) * self.visits()[keep].min(axis=1)).sum())

    def totals(self) -> np.ndarray:
        """(clusters, 2) transitions per cluster and side over all states."""
        return np.bincount(2 * self.cluster + self.side, weights=self.count,
                           minlength=2 * self.n_clusters).reshape(self.n_clusters, 2)


@dataclass(frozen=True, slots=True, eq=False)
class ClusterSums:
    """Per entering state and cluster: the sums and the products of sums the cluster variances
    need, as a (width · states) × clusters matrix, so that any resampling weights of the
    clusters give every replicate's moments and variances with one product."""

    matrix: np.ndarray | sp.csc_matrix | ProductColumns  # (width · states) × clusters
    visits: np.ndarray | sp.csr_matrix  # (states · 2) × clusters: the side-k member visits
    totals: np.ndarray  # (clusters, 2)
    column: dict
    n_states: int
    features: int
    pairs: bool

    @classmethod
    def of(cls, entries: Entries, keep: np.ndarray) -> ClusterSums:
        new_index = np.cumsum(keep) - 1
        take = keep[entries.state]
        state = new_index[entries.state[take]]
        side, cluster = entries.side[take], entries.cluster[take]
        n_states, n_clusters = int(keep.sum()), entries.n_clusters
        j = entries.first.shape[1]
        sums = np.hstack([entries.count[take, None], entries.first[take], entries.second[take]])
        width = sums.shape[1]  # per side N, S1, S2 of each feature
        spec = _product_spec(j, entries.pairs)
        column = {name: i for i, (name, _, _) in enumerate(spec)}
        one, two = (np.array([-1 if f is None else f[0] * width + f[1] for f in factors])
                    for factors in zip(*(factors for _, *factors in spec), strict=True))
        parts = [(cluster[side == k], state[side == k], sums[side == k]) for k in (0, 1)]
        matrix = unit_matrix(parts, n_clusters, n_states, products=(one, two))
        visits = _visits(2 * state + side, cluster, 2 * n_states, n_clusters)
        return cls(matrix, visits, entries.totals(), column, n_states, j, entries.pairs)

    def deviation(self, weights: np.ndarray) -> dict[str, np.ndarray]:
        """(features, replicates) plug-in and bias-corrected squared deviations and shifts, each
        cluster counted ``weights[cluster, r]`` times in replicate ``r``."""
        out = {name: np.zeros((self.features, weights.shape[1]))
               for name in ("plugin", "squared", "shift")}
        for j, c in enumerate(self.components(weights)):
            plugin = c.d_mean**2 + c.d_sd**2
            out["plugin"][j] = (c.w * plugin).sum(axis=0)
            out["squared"][j] = (c.w * (plugin - (c.var_mean + c.var_sd))).sum(axis=0)
            out["shift"][j] = (c.w_shift * c.shift).sum(axis=0)
        return out

    def components(self, weights: np.ndarray, pair_covariance: bool = True,
                   second_order: bool = False) -> list[StateComponents]:
        """Per feature, the per-(state, replicate) terms :meth:`deviation` sums. For
        scripts/deviation_noise_probe.py: ``pair_covariance=False`` leaves the pair members'
        covariance out of the variances, ``second_order=True`` adds to each side's variance of
        ``v̂`` the variance ``2 V̂_μ²`` of its quadratic term ``(μ̂ − μ)²``."""
        get, count, inflate = self.weighted(weights)
        drawn = np.asarray(self.visits @ (weights > 0)).reshape(self.n_states, 2, -1)
        total = self.totals.T @ weights  # (2, r)
        usable = (drawn >= MIN_UNITS).all(axis=1)  # θ: a variance between units needs two
        present = (drawn >= 1).all(axis=1)  # the shift: a mean needs one (module docs)
        w, w_shift = (normalised(np.where(keep, 0.5 * (count[0] / total[0]
                                                         + count[1] / total[1]), 0.0))
                      for keep in (usable, present))
        def feature(j: int) -> StateComponents:
            with np.errstate(invalid="ignore", divide="ignore"):
                a, b = [_side_moments(get, count[k], inflate[k], k, j, second_order)
                        for k in (0, 1)]
                var_mean = a["var_mean"] + b["var_mean"]
                var_sd = a["var_sd"] + b["var_sd"]
                if self.pairs and pair_covariance:  # the members are resampled together
                    cov_mean, cov_var = _pair_covariances(get, count, inflate, a, b, j)
                    var_mean = var_mean - 2 * cov_mean
                    rho = np.clip(cov_var / np.sqrt(a["var_v"] * b["var_v"]), -1.0, 1.0)
                    var_sd = var_sd - 2 * np.nan_to_num(rho) * np.sqrt(a["var_sd"] * b["var_sd"])
            return StateComponents(
                w, w_shift, np.where(usable, a["mean"] - b["mean"], 0.0),
                np.where(usable, a["sd"] - b["sd"], 0.0),
                np.where(usable, np.maximum(var_mean, 0.0), 0.0),
                np.where(usable, np.maximum(var_sd, 0.0), 0.0),
                np.where(present, a["mean"] - b["mean"], 0.0))

        return in_threads(feature, range(self.features))

    def weighted(self, weights: np.ndarray) -> tuple[Callable, list, list]:
        """The replicates' sums: a getter of one named (states, replicates) sum, each side's
        transitions and the leverage correction of each side's cluster variances."""
        q = np.asarray(self.matrix @ weights).reshape(-1, self.n_states, weights.shape[1])

        def get(*name):
            return q[self.column[name]]

        count = [get("N", k) for k in (0, 1)]
        with np.errstate(invalid="ignore", divide="ignore"):
            inflate = [1.0 / (1.0 - np.minimum(get("NN", k) / count[k]**2, 1.0))
                       for k in (0, 1)]  # leverage correction of the cluster variance
        return get, count, inflate


@dataclass(frozen=True, slots=True, eq=False)
class StateComponents:
    """One feature's (states, replicates) terms of the deviation: the state weights of ``θ``
    and of the shift, the mean and standard-deviation differences (0 where a state is not
    usable), their cluster variances (the noise ``θ̃`` subtracts) and the shift's difference."""

    w: np.ndarray
    w_shift: np.ndarray
    d_mean: np.ndarray
    d_sd: np.ndarray
    var_mean: np.ndarray
    var_sd: np.ndarray
    shift: np.ndarray


def _visits(row: np.ndarray, cluster: np.ndarray, n_rows: int, n_clusters: int
            ) -> np.ndarray | sp.csr_matrix:
    """The (rows × clusters) count of entries at each (row, cluster): dense float32 where at
    least :data:`VISITS_DENSE_SHARE` of the positions hold one (its products with 0/1 weights
    count clusters, below 2**24: exact), else CSR (float64, as before)."""
    if len(row) >= VISITS_DENSE_SHARE * n_rows * n_clusters and n_clusters < 2**24:
        counts = np.bincount(row * n_clusters + cluster, minlength=n_rows * n_clusters)
        return counts.astype(np.float32).reshape(n_rows, n_clusters)
    return sp.csr_matrix((np.ones(len(row)), (row, cluster)), shape=(n_rows, n_clusters))


def normalised(share: np.ndarray) -> np.ndarray:
    """``share`` divided by its sum over the states (axis 0); zero where that sum is 0."""
    total = share.sum(axis=0)
    return share / np.where(total > 0, total, 1.0)


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


def _side_moments(get, n, inflate, k, j, second_order: bool = False
                  ) -> dict[str, np.ndarray]:
    """Mean, standard deviation and their cluster variances of one side in every state
    (``second_order``: :meth:`ClusterSums.components`)."""
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
    spread_v = var_v + 2 * var_mean**2 if second_order else var_v
    var_sd = np.minimum(spread_v / (4 * var), var)  # delta method, at most the variance itself
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
