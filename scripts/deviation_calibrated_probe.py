"""The response deviation's bias correction calibrated by the design's own assignments, and
intervals around it, against the shipped correction (issue 21, interval coverage; paired
designs, tests/response_designs.py ``defect``, seeds 0 to ``--reps`` − 1).

Per entering state, the plug-in's squared differences less their mean over the assignments
(the pairs' members swapped) under which the state would still enter (each side ≥
``MIN_UNITS`` units and ≥ ``MIN_SHARE`` of its transitions: the observed labels are selected
by that rule), divided by ``1 − h`` (``h = Σ_c (N_c / N)²`` over the pairs' transitions in the
state: under a difference ``δ`` the assignments' mean holds ``h δ²``), summed with the observed
state weights. Under the same law the observed labels are one of the assignments, so the
correction is exact there. Three intervals around it (:func:`_calibrated`), scored for
coverage of the bracketed truths (deviation_noise_probe.py ``--truth``) and for equivalence
declared at the truth. The ``v_`` fields: the same with the standard deviations' part taken
through the variances, ``(v̂_A − v̂_B)²`` calibrated and divided by the observed
``(σ̂_A + σ̂_B)²`` (:func:`_variance_parts`). ``permutation_mixing`` (session 23): the same
estimate over ``1 − E(a − b)²`` instead of ``1 − h``, the mean over the entering assignments of
the exact mixing of the two laws on each side (:func:`_mixing`; ``leverage_mean`` and
``mixing_mean`` are the two factors' weighted means). ``permutation_kurtosis`` (session 23):
the calibrated estimate with the standard deviation's excess less the observed labels' noise
of ``σ̂`` over the entering assignments' mean noise (each side's delta-method noise from its own
central moments, :func:`_sd_noise`; a swapped side mixes the two laws, whose excess kurtosis
makes ``σ̂`` noisier than under the observed labels); ``permutation_kurtosis_units`` the same
with the noise between units (:func:`_sd_noise_units`); the ``u_`` fields: the three intervals
moved to that estimate (the same laws of the noise, centred on the corrected estimate; taking
each assignment's standard-deviation part less its own noise as the law instead narrowed it
to 26–36 % coverage at 90 %: the noise estimate moves with the noise it estimates).
``u_inv`` / ``c_inv`` (session 24): the test-inversion interval (:func:`inverted_bounds`) of the
corrected / the calibrated estimate: at each candidate ``θ₀`` the estimate's law is taken as
``θ₀`` plus the assignments' law of the noise plus a normal linear term whose variance ``κ θ₀``
grows with the candidate (the deviation spread over the states as the calibrated squares), so
the upper bound's width is set by the deviation it tests, not by the estimate. ``g_inv``: the
same with ``κ`` from the pairs' influences across states (:func:`_kappa_pairs`); ``uc_inv`` and
``gc_inv``: those two with the upper bound by CLs (:func:`inverted_bounds`). ``r_inv``: ``κ``
as the pairs' linear variance less its noise (``law_pairs``'s) over the corrected estimate, the
per-state ``κ`` where either is not positive; ``rp16_inv`` / ``rp50_inv``: ``r_inv`` with a
power-constrained upper bound at 16 % / 50 % power (:func:`inverted_bounds`); ``rf_inv``
(session 25): ``r_inv`` with the shipped bound's floor instead (:func:`_floored`);
``floor_median`` / ``floor_above_truth``: that floor's median (squared, at α = 0.05) and the
share of draws in which it is above the squared truth.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/deviation_calibrated_probe.py \
        --reps 200 --bracketed benchmarks/results/deviation_noise_probe_truth.json \
        --out benchmarks/results/deviation_noise_probe_permutation.json
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "scripts"))
from deviation_noise_probe import RESPONSES, _root, bracketed, replications  # noqa: E402

from simcred.compare import effect  # noqa: E402
from simcred.compare.cluster_sums import MIN_SHARE, MIN_UNITS, Entries  # noqa: E402


def permutation_recording(into: list):
    """``response_effects`` that also appends, per call and response, the shipped ``θ̃``, the
    permutation-calibrated one with and without ``1 / (1 − h)`` (module docs) and the bounds of
    three intervals around the calibrated one (:func:`_calibrated`)."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        found = assignment_parts(data, design, args[6])  # (..., rng, assignments)
        parts, entering, weight = found.parts, found.entering, found.weight
        leverage, per_pair = found.leverage, found.per_pair
        valid_mixing = found.mixing[:, 1:] * entering[:, 1:]
        mixing = valid_mixing.sum(axis=1) / np.maximum(entering[:, 1:].sum(axis=1), 1)
        # the variance route: (Δv)² calibrated, over the observed (σ̂_A + σ̂_B)²
        by_variance = np.stack([parts[0], parts[2] / np.where(
            parts[3][..., :1] > 0, parts[3][..., :1], np.inf)])
        rng, valid = np.random.default_rng(len(into)), entering[:, 1:]
        row = {}
        for k, f in enumerate(out.features):
            linear = _pairs_linear_variance(per_pair, weight / (1 - leverage), k)
            excess = calibrated_excess(parts[:2, k], entering[:, 1:])[0].sum(axis=0)
            extra_noise = calibrated_excess(parts[4, k], entering[:, 1:])[0]
            extra_unit_noise = calibrated_excess(parts[5, k], entering[:, 1:])[0]
            row[f.feature] = {"shipped": f.squared,
                              "permutation_kurtosis": float(
                                  (weight * (excess - extra_noise) / (1 - leverage)).sum()),
                              "permutation_kurtosis_units": float(
                                  (weight * (excess - extra_unit_noise) / (1 - leverage)).sum()),
                              "permutation_mixing": float((weight * np.where(
                                  mixing < 1 - 1e-9, excess, 0.0) / np.maximum(
                                  1 - mixing, 1e-9)).sum()),
                              "leverage_mean": float((weight * leverage).sum()),
                              "mixing_mean": float((weight * mixing).sum())} | _calibrated(
                parts[:2, k], valid, weight, leverage, rng, linear) | {
                f"v_{name}": value for name, value in _calibrated(
                    by_variance[:, k], valid, weight, leverage,
                    np.random.default_rng(len(into)), linear).items()}
            shift = row[f.feature]["permutation_kurtosis_units"] \
                - row[f.feature]["permutation_leverage"]
            row[f.feature] |= {f"u_{name}": value + shift for name, value in row[f.feature].items()
                               if name.startswith("law")}
            row[f.feature] |= _inverted_fields(
                row[f.feature], _noise_law(parts[:2, k], valid, weight, leverage), weight,
                leverage, (per_pair, k), linear, np.random.default_rng(10_000 + len(into)))
            row[f.feature] |= _floored(row[f.feature], "r_inv", f)
        into.append(row)
        return out
    return wrapped


def _inverted_fields(row: dict, noise_law, weight, leverage, pairs: tuple, linear: float,
                     rng) -> dict[str, float]:
    """The inverted intervals' bounds (module docs: ``u_inv`` ... ``rp50_inv``) of one response,
    from its ``row`` of estimates, :func:`_noise_law`'s output, the pairs' sums and response
    index (:func:`_kappa_pairs`) and the pairs' linear variance less its noise."""
    excess, null, law = noise_law
    kappa = _linear_per_theta(excess, null, weight, leverage)
    kappa_pairs = _kappa_pairs(*pairs, excess, weight, leverage)
    by_pairs = kappa if kappa_pairs is None else kappa_pairs
    corrected = row["permutation_kurtosis_units"]
    # the linear term's variance estimated at the truth, its noise removed, per unit θ
    ratio = linear / corrected if linear > 0 and corrected > 0 else kappa
    normal = rng.standard_normal(10 * len(law))
    out = {}
    for prefix, estimate, factor, cls, power in (
            ("u_", corrected, kappa, False, 0.0),
            ("c_", row["permutation_leverage"], kappa, False, 0.0),
            ("g_", corrected, by_pairs, False, 0.0),
            ("uc_", corrected, kappa, True, 0.0),
            ("gc_", corrected, by_pairs, True, 0.0),
            ("r_", corrected, ratio, False, 0.0),
            ("rp16_", corrected, ratio, False, 0.16),
            ("rp50_", corrected, ratio, False, 0.5)):
        out |= {prefix + name: value for name, value in inverted_bounds(
            estimate, law, factor, normal, cls, power).items()}
    return out


def _floored(row: dict, interval: str, shipped) -> dict[str, float]:
    """``rf_inv`` (session 25): ``interval``'s bounds with the upper end never below the
    shipped effect's power floor at the same tail (effect.py, "Power constraint")."""
    out = {"floor": shipped.power_floor(0.05)}
    for level in (0.90, 0.95):
        out[f"rf_inv_{level}_low"] = row[f"{interval}_{level}_low"]
        out[f"rf_inv_{level}_high"] = max(row[f"{interval}_{level}_high"],
                                          shipped.power_floor((1 - level) / 2))
    return out


@dataclass(frozen=True)
class AssignmentParts:
    """The design's sums (``entries``) and, per entering state: the plug-in's parts under every
    assignment (4, features, states, P + 1: mean and standard-deviation squared differences,
    then the squared difference of the variances and the squared sum of the standard
    deviations; column 0 observed), whether the state would enter under each (states, P + 1),
    the observed weights, ``h`` and the sums per pair (:func:`_per_pair`)."""

    entries: Entries
    keep: np.ndarray
    parts: np.ndarray
    entering: np.ndarray
    weight: np.ndarray
    leverage: np.ndarray
    per_pair: np.ndarray
    mixing: np.ndarray


def assignment_parts(data, design, assignments: np.ndarray) -> AssignmentParts:
    entries = Entries.of(data, design)
    keep = entries.entering()
    take = keep[entries.state]
    state, count = (np.cumsum(keep) - 1)[entries.state[take]], entries.count[take]
    visits = np.zeros((int(keep.sum()), assignments.shape[1]))
    visits[state, entries.unit[take]] = 1.0
    higher = _higher_sums(data, state, entries.unit[take], take, visits.shape)
    unit_products = _unit_products(entries, take, state, visits.shape)
    from_a = np.zeros_like(visits)  # A's transitions per state and unit (B's units: 0)
    on_a = entries.side[take] == 0
    from_a[state[on_a], entries.unit[take][on_a]] = count[on_a]
    leverage = pair_leverage(entries, keep)
    j = entries.first.shape[1]
    parts, entering, weight, mixing = [], [], None, []
    for start, sides, total in effect.assignment_sides(entries, keep, assignments):
        w, mean_part, sd_part = effect.plugin_terms(sides, total, j)
        units_a = visits @ assignments[start:start + w.shape[-1]].T
        mixing.append(_mixing(from_a, assignments[start:start + w.shape[-1]], sides))
        units = [units_a, visits.sum(axis=1, keepdims=True) - units_a]
        entering.append(np.all([(u >= MIN_UNITS) & (c[0] / t >= MIN_SHARE)
                                for u, c, t in zip(units, sides, total, strict=True)],
                               axis=0))
        parts.append(np.stack([mean_part, sd_part, *_variance_parts(sides, j),
                               _sd_noise(sides, higher, assignments[start:start + w.shape[-1]],
                                         j),
                               _sd_noise_units(sides, unit_products,
                                               assignments[start:start + w.shape[-1]], j)]))
        weight = w[:, 0] if weight is None else weight  # the observed row's
    return AssignmentParts(entries, keep, np.concatenate(parts, axis=-1),
                           np.concatenate(entering, axis=-1), weight, leverage,
                           _per_pair(entries, take, state), np.concatenate(mixing, axis=-1))


def pair_leverage(entries: Entries, keep: np.ndarray) -> np.ndarray:
    """Per entering state, ``h = Σ_c (N_c / N)²`` over the pairs' transitions in it."""
    take = keep[entries.state]
    by_pair = np.zeros((int(keep.sum()), entries.n_clusters))
    np.add.at(by_pair, ((np.cumsum(keep) - 1)[entries.state[take]], entries.cluster[take]),
              entries.count[take])
    return ((by_pair / by_pair.sum(axis=1, keepdims=True))**2).sum(axis=1)


def _higher_sums(data, state: np.ndarray, unit: np.ndarray, take: np.ndarray,
                 shape: tuple[int, int]) -> np.ndarray:
    """(2, J, entering states, units) sums of each response's residual cubed and to the fourth
    power per (state, unit), grouped as :meth:`Entries.of` groups the transitions."""
    new = np.r_[True, (data.state[1:] != data.state[:-1]) | (data.unit[1:] != data.unit[:-1])]
    starts = np.flatnonzero(new)
    x = data.effect_residual
    out = np.zeros((2, x.shape[1], *shape))
    for p, power in enumerate((3, 4)):
        sums = np.add.reduceat(x**power, starts, axis=0)[take]
        for k in range(x.shape[1]):
            out[p, k, state, unit] = sums[:, k]
    return out


def _side_moments(side: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A side's transitions (at least 1), mean and variance per response from its (1 + 2J, ...)
    sums."""
    n = np.maximum(side[0], 1.0)
    mean = side[1:1 + j] / n
    return n, mean, np.maximum(side[1 + j:] / n - mean**2, 0.0)


def _sd_noise(sides, higher: np.ndarray, assignments: np.ndarray, j: int) -> np.ndarray:
    """(J, states, k) the delta-method noise of ``σ̂`` on each side, ``(m4 − m2²) / (4 m2 n)``
    from the side's own central moments, summed over the two sides."""
    third_a, fourth_a = (higher[p] @ assignments.T.astype(np.float64) for p in (0, 1))
    pooled = higher.sum(axis=-1, keepdims=True)
    noise = 0.0
    for s, third, fourth in ((sides[0], third_a, fourth_a),
                             (sides[1], pooled[0] - third_a, pooled[1] - fourth_a)):
        n, mean, m2 = _side_moments(s, j)
        raw2, raw3, raw4 = s[1 + j:] / n, third / n, fourth / n
        m4 = raw4 - 4 * mean * raw3 + 6 * mean**2 * raw2 - 3 * mean**4
        with np.errstate(invalid="ignore", divide="ignore"):
            noise = noise + np.nan_to_num((m4 - m2**2) / (4 * m2 * n))
    return noise


def _unit_products(entries: Entries, take: np.ndarray, state: np.ndarray,
                   shape: tuple[int, int]) -> np.ndarray:
    """(6, J, entering states, units) per-(state, unit) products of the count ``N`` and the sums
    ``S1``, ``S2`` of each response's residual and its square: ``S2², S1², N², S2 S1, S2 N,
    S1 N`` (what each side's between-unit noise of ``σ̂`` needs, :func:`_sd_noise_units`)."""
    n = entries.count[take, None] * np.ones_like(entries.first[take])
    s1, s2 = entries.first[take], entries.second[take]
    out = np.zeros((6, s1.shape[1], *shape))
    unit = entries.unit[take]
    for p, value in enumerate((s2 * s2, s1 * s1, n * n, s2 * s1, s2 * n, s1 * n)):
        for k in range(s1.shape[1]):
            out[p, k, state, unit] = value[:, k]
    return out


def _sd_noise_units(sides, products: np.ndarray, assignments: np.ndarray, j: int
                    ) -> np.ndarray:
    """(J, states, k) each side's noise of ``σ̂`` between its units, summed over the sides:
    ``Σ_u e_u² / (4 m2 n²)`` with ``e_u = S2_u − 2 μ S1_u + (μ² − m2) N_u`` (the unit's sum of
    the influence ``(x − μ)² − m2``), from the side sums of :func:`_unit_products`."""
    side_a = products @ assignments.T.astype(np.float64)  # (6, J, states, k)
    pooled = products.sum(axis=-1, keepdims=True)
    noise = 0.0
    for s, q in ((sides[0], side_a), (sides[1], pooled - side_a)):
        n, mean, m2 = _side_moments(s, j)
        c = mean**2 - m2
        squares = (q[0] + 4 * mean**2 * q[1] + c**2 * q[2] - 4 * mean * q[3] + 2 * c * q[4]
                   - 4 * mean * c * q[5])
        with np.errstate(invalid="ignore", divide="ignore"):
            noise = noise + np.nan_to_num(squares / (4 * m2 * n**2))
    return noise


def _mixing(from_a: np.ndarray, assignments: np.ndarray, sides) -> np.ndarray:
    """Per state and assignment, ``(a − b)²``: ``a`` the share of A's own transitions on the
    assignment's side A, ``b`` on its side B. A mean difference ``δ`` shows as ``(a − b) δ``
    under the assignment whatever the two sides' levels (each side is a mixture of the two
    laws), so its assignments' mean leaks ``E(a − b)² δ²`` (1 for the observed labels)."""
    own_a = from_a @ assignments.T.astype(np.float64)
    a = own_a / np.maximum(sides[0][0], 1.0)
    b = (from_a.sum(axis=1, keepdims=True) - own_a) / np.maximum(sides[1][0], 1.0)
    return (a - b)**2


def calibrated_excess(parts: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per part and state, the observed squared difference less its mean over the assignments
    under which the state enters (``valid``, states × P), and that mean (the observed value
    where none does)."""
    entered = valid.any(axis=1)
    null = np.where(entered, (parts[..., 1:] * valid).sum(axis=-1)
                    / np.maximum(valid.sum(axis=1), 1), parts[..., 0])
    return parts[..., 0] - null, null


def _variance_parts(sides, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Per feature, state and assignment: the squared difference of the two sides' variances
    ``(v̂_A − v̂_B)²`` and the squared sum of their standard deviations ``(σ̂_A + σ̂_B)²``
    (``(σ_A − σ_B)² = (v_A − v_B)² / (σ_A + σ_B)²``)."""
    count = [s[0] for s in sides]
    with np.errstate(invalid="ignore", divide="ignore"):
        var = [np.maximum(s[1 + j:] / c - (s[1:1 + j] / c)**2, 0.0)
               for s, c in zip(sides, count, strict=True)]
    return (np.nan_to_num((var[0] - var[1])**2),
            np.nan_to_num((np.sqrt(var[0]) + np.sqrt(var[1]))**2))


def _per_pair(entries: Entries, take: np.ndarray, state: np.ndarray) -> np.ndarray:
    """(1 + 2J, 2, states, pairs) sums of the entering states' transitions per side and pair:
    the count, then the sums of each response's residual, then of its square."""
    values = np.hstack([entries.count[take, None], entries.first[take], entries.second[take]])
    sums = np.zeros((values.shape[1], 2, int(state.max(initial=-1)) + 1, entries.n_clusters))
    for i in range(values.shape[1]):
        np.add.at(sums[i], (entries.side[take], state, entries.cluster[take]), values[:, i])
    return sums


def _pair_influences(per_pair: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Response ``k``'s pairs' influences on every entering state's difference of means and of
    standard deviations (pairs, 2 · states), and those differences (2 · states)."""
    j = (len(per_pair) - 1) // 2
    sums = per_pair[[0, 1 + k, 1 + j + k]]  # N, S1, S2 per side, state, pair
    n, s1, s2 = (x.sum(axis=-1, keepdims=True) for x in sums)  # (2, states, 1)
    mean, var = s1 / n, np.maximum(s2 / n - (s1 / n)**2, 0.0)
    sd = np.sqrt(var)
    psi_mean = (sums[1] - mean * sums[0]) / n
    with np.errstate(invalid="ignore", divide="ignore"):
        psi_sd = np.nan_to_num((sums[2] - 2 * mean * sums[1] + (mean**2 - var) * sums[0])
                               / (2 * sd * n))
    psi = np.vstack([psi_mean[0] - psi_mean[1], psi_sd[0] - psi_sd[1]]).T
    return psi, np.r_[(mean[0] - mean[1])[:, 0], (sd[0] - sd[1])[:, 0]]


def _pairs_linear_variance(per_pair: np.ndarray, weight: np.ndarray, k: int) -> float:
    """The variance of the linear term ``Σ_s 2 w_s δ_s e_s`` of the calibrated estimate from
    the pairs' own influences ``ψ_c`` on every state's difference of means and of standard
    deviations (so pairs that visit several states carry their covariance): ``4 Σ_c L̂_c²``
    with ``L̂_c = Σ w δ̂ ψ_c``, less its noise ``4 wᵀ (G ∘ G) w`` (``G = Ψᵀ Ψ``: ``δ̂ δ̂ᵀ``
    holds ``δ δᵀ + G``), at least 0. ``per_pair``: :func:`_per_pair`; ``weight``: the states'
    ``w / (1 − h)``."""
    psi, difference = _pair_influences(per_pair, k)
    w2 = np.r_[weight, weight]
    coefficient = w2 * difference
    gram = psi.T @ psi
    return max(4 * float(((psi @ coefficient)**2).sum() - w2 @ (gram * gram) @ w2), 0.0)


def _kappa_pairs(per_pair: np.ndarray, k: int, excess: np.ndarray, weight: np.ndarray,
                 leverage: np.ndarray) -> float | None:
    """``κ`` from the pairs' influences across states (their covariance kept): the deviation
    spread as the calibrated squares with the observed differences' signs, ``f``, and ``κ =
    4 Σ_c (ψ_c · (w' ∘ f))² / Σ w f²`` (``w' = w / (1 − h)``); None where no square is
    positive."""
    psi, difference = _pair_influences(per_pair, k)
    square = (np.maximum(excess, 0.0) / (1 - leverage)).ravel()  # (2 · states): mean, sd
    total = float((np.r_[weight, weight] * square).sum())
    if total <= 0:
        return None
    shape = np.sign(difference) * np.sqrt(square)
    coefficient = np.r_[weight, weight] / np.r_[1 - leverage, 1 - leverage] * shape
    return 4 * float(((psi @ coefficient)**2).sum()) / total


def _calibrated(parts, valid, weight, leverage, rng, pairs_variance: float = 0.0
                ) -> dict[str, float]:
    """The calibrated estimate and its three intervals' bounds from the (mean, sd) parts' squared
    differences (2, states, P + 1) under every assignment (column 0 observed), the states'
    entry under each (states, P) and the observed weights: the estimate less, per state, the
    parts' mean over the assignments under which it enters, over ``1 − h``; the assignments'
    law of that estimate (each assignment as the observed one; the law of the noise, exact
    under the same law), and that law plus a normal linear term: ``4 Σ w² T c`` (``T`` a part's
    calibrated square, ``c`` its assignments' mean: the variance of ``2 δ e`` where ``δ ≠ 0``,
    per state), or ``pairs_variance`` (:func:`_pairs_linear_variance`, across states)."""
    excess, null, law = _noise_law(parts, valid, weight, leverage)
    estimate = float((weight * excess.sum(axis=0) / (1 - leverage)).sum())
    linear = max(4 * float((weight**2 * (excess / (1 - leverage) * null).sum(axis=0)).sum()),
                 0.0)
    normal = rng.standard_normal(10 * len(law))
    wide = np.repeat(law, 10) + np.sqrt(linear) * normal
    out = {"permutation": float((weight * excess.sum(axis=0)).sum()),
           "permutation_leverage": estimate, "assignments_entering": float(valid.mean())}
    for name, values in (("law", law), ("law_linear", wide),
                         ("law_pairs", np.repeat(law, 10) + np.sqrt(pairs_variance) * normal)):
        for level in (0.90, 0.95):
            tail = (1 - level) / 2
            out[f"{name}_{level}_low"] = estimate - float(np.quantile(values, 1 - tail))
            out[f"{name}_{level}_high"] = estimate - float(np.quantile(values, tail))
    return out


def _noise_law(parts, valid, weight, leverage) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`calibrated_excess` of the (mean, sd) parts and the assignments' law of the
    calibrated estimate (each assignment taken as the observed one)."""
    excess, null = calibrated_excess(parts, valid)
    w_k = weight[:, None] * valid
    law = (w_k * (parts[..., 1:] - null[..., None]).sum(axis=0) / (1 - leverage)[:, None]
           ).sum(axis=0) / np.maximum(w_k.sum(axis=0), 1e-300)
    return excess, null, law


def _linear_per_theta(excess, null, weight, leverage) -> float:
    """``κ``: the variance of the linear term ``Σ 2 w δ e`` per unit of ``θ`` when the
    deviation is spread over the states and parts as the calibrated squares (clipped at 0;
    as the noise where none is positive): ``4 Σ w² f c`` with ``Σ w f = 1``."""
    shape = np.maximum(excess, 0.0) / (1 - leverage)
    if (weight * shape.sum(axis=0)).sum() <= 0:
        shape = null.copy()
    total = float((weight * shape.sum(axis=0)).sum())
    return 4 * float((weight**2 * (shape * null).sum(axis=0)).sum()) / max(total, 1e-300)


def inverted_bounds(estimate: float, law: np.ndarray, kappa: float, normal: np.ndarray,
                    cls: bool = False, power: float = 0.0) -> dict[str, float]:
    """Test inversion at ``θ₀``: the estimate's law there taken as ``θ₀ + N + √(κ θ₀) Z`` (``N``
    the assignments' law of the noise, ``Z`` the fixed normal draws, 10 per assignment); the
    bounds where the observed estimate is at its upper / lower ``(1 − level) / 2`` tail, on
    the squared scale (the lower bound at least 0). ``cls``: the upper bound by CLs (Read
    2002): ``θ₀`` excluded only where ``P_θ₀(T ≤ t) / P_0(T ≤ t)`` is at most the tail, so that
    an estimate below all that the noise gives cannot exclude deviations the data cannot
    tell from 0 (each probability counted with one added draw). ``power``: a power-constrained
    upper bound (Cowan, Cranmer, Gross & Vitells 2011): at least the smallest ``θ₀`` that the
    test excludes with probability ``power`` when the deviation is 0."""
    noise, z = np.repeat(law, len(normal) // len(law)), normal

    def above(theta):  # P(estimate under θ₀ ≥ observed)
        return float((theta + noise + np.sqrt(kappa * max(theta, 0.0)) * z >= estimate).mean())

    def below(theta):  # P(estimate under θ₀ ≤ observed), one draw added
        hits = (theta + noise + np.sqrt(kappa * max(theta, 0.0)) * z <= estimate).sum()
        return float((hits + 1) / (len(z) + 1))

    def excluded(theta):  # 1 − CLs: increasing in θ₀ like ``above``
        return 1 - below(theta) / below(0.0)

    def power_at_zero(theta, tail):  # P_0(the test at θ₀ excludes θ₀)
        cut = np.quantile(theta + noise + np.sqrt(kappa * max(theta, 0.0)) * z, tail)
        return float((noise < cut).mean())

    top = 20 * abs(estimate) + 20 * float(np.abs(law).max()) + 1e-12
    out = {}
    for level in (0.90, 0.95):
        tail = (1 - level) / 2
        out[f"inv_{level}_low"] = 0.0 if above(0.0) >= tail else _root(above, top, tail)
        if cls:
            out[f"inv_{level}_high"] = _root(excluded, top, 1 - tail)
        else:
            out[f"inv_{level}_high"] = 0.0 if above(0.0) >= 1 - tail else _root(
                above, top, 1 - tail)
        if power > 0:
            out[f"inv_{level}_high"] = max(out[f"inv_{level}_high"], _root(
                lambda theta, tail=tail: power_at_zero(theta, tail), top, power))
    return out


def permutation_summary(kind: str, rows: list, truth: dict) -> dict:
    """Per response, the mean (± its standard error) and the sampling sd over the replications
    of the shipped and the permutation-calibrated ``θ̃``, against the squared truth; each
    interval's coverage, misses low, mean width and equivalence declared at the truth (its
    90 % interval's high end is the one-sided 95 % upper bound)."""
    out = {}
    for name in RESPONSES:
        t2 = truth.get(name, 0.0)**2
        cell = {"truth_squared": t2}
        for method in ("shipped", "permutation", "permutation_leverage",
                       "assignments_entering", "v_permutation_leverage", "permutation_mixing",
                       "permutation_kurtosis", "permutation_kurtosis_units",
                       "leverage_mean", "mixing_mean"):
            v = np.array([r[name][method] for r in rows])
            cell[method] = float(v.mean())
            cell[f"{method}_se"] = float(v.std(ddof=1) / np.sqrt(len(v)))
            cell[f"{method}_sd"] = float(v.std(ddof=1))
        floor = np.array([r[name]["floor"] for r in rows])
        cell["floor_median"] = float(np.median(floor))
        cell["floor_above_truth"] = float(np.mean(floor > t2))
        for interval in ("law", "law_linear", "law_pairs", "v_law", "v_law_linear",
                         "v_law_pairs", "u_law", "u_law_linear", "u_law_pairs", "u_inv", "c_inv",
                         "g_inv", "uc_inv", "gc_inv", "r_inv",
                         "rp16_inv", "rp50_inv", "rf_inv"):
            for level in (0.90, 0.95):
                low = np.array([r[name][f"{interval}_{level}_low"] for r in rows])
                high = np.array([r[name][f"{interval}_{level}_high"] for r in rows])
                cell[f"{interval}_{level}"] = float(np.mean((low <= t2) & (t2 <= high)))
                cell[f"{interval}_{level}_low_above"] = float(np.mean(low > t2))
                cell[f"{interval}_{level}_width"] = float(np.mean(high - low))
                if level == 0.90:
                    cell[f"{interval}_equivalent_at_truth"] = float(np.mean(high < t2))
        print(kind, name, json.dumps({k: round(v, 6) for k, v in cell.items()}), flush=True)
        out[name] = cell
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="none,variance,delay,clip")
    parser.add_argument("--reps", type=int, default=80)
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--permutations", type=int, default=199)
    parser.add_argument("--seed0", type=int, default=0, help="the first replication's seed")
    parser.add_argument("--bracketed", required=True, metavar="TRUTH_JSON",
                        help="a deviation_noise_probe.py --truth output")
    parser.add_argument("--out", default="deviation_calibrated_probe.json")
    args = parser.parse_args(argv)
    truths, table = bracketed(args.bracketed), {}
    for kind in args.kinds.split(","):
        rows: list = []
        replications(permutation_recording(rows), kind, args.reps, args.runs, args.seed0, 2,
                     permutations=args.permutations)
        table[kind] = permutation_summary(kind, rows, truths.get(kind, {}))
    Path(args.out).write_text(json.dumps({"args": vars(args), "table": table}, indent=1))


if __name__ == "__main__":
    main()
