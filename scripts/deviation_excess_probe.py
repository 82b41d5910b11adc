"""Six intervals of the response deviation built on what its bootstrap gets wrong (issue 21,
interval coverage; session 29). None is shipped (docs/calibration.md, "Session 29").

The bootstrap world's per-state differences are the sample's ``d̂_s = Δ_s + e_s``, so the linear
term of ``θ̃* − θ̂``, ``Σ_c (Σ_s 2 w_s d̂_s ψ_cs)²`` over the units ``c`` (``ψ_cs`` a unit's
influence on state ``s``'s difference of means and of standard deviations), carries besides
the real world's ``Σ_c (Σ_s 2 w_s Δ_s ψ_cs)²`` the sample's noise, ``4 wᵀ(G∘G)w`` in
expectation (``G = ΨᵀΨ``). Per replication (``--pairs`` pairs of a defect design, seeds from
``--seed0``, ``--permutations`` assignments for the plug-in's null) and response, from 500
replicates of its own (``ClusterSums.components``, column 0 the sample), beside the shipped
interval (``shipped``, the comparison's own 500 replicates):

* ``scaled``: the basic interval of the squared deviation on replicates moved toward the
  bootstrap world's value, ``θ̂ + k (θ̃* − θ̂)``, ``k = √(max(var* − 4 wᵀ(Ĝ∘Ĝ)w, 0) / var*)``;
  ``scaled_shipped``: the shipped bounds (stabilised lower bound, floored upper) of the same;
* ``student``: bootstrap-t, ``θ̃ − se · q(t*)``, ``t* = (θ̃* − θ̂) / se*``, with the per-state
  error ``se² = max(Σ w² Σ_m (4 (d² − V) V + 2 V²), Σ w² Σ_m V²)`` (``m``: mean and sd);
  ``student_cross`` (``--cross``): the same with the error across states, ``4 Σ_c w_c L_c² − 2
  wᵀ(G∘G)w`` (at least ``wᵀ(G∘G)w``), ``L_c = Σ_s w_s d_s ψ_cs``, each replicate's own;
* ``boot_inv``: test inversion with the law ``θ₀ + Q* + √(κ θ₀) Z`` at each candidate ``θ₀``,
  ``Q* = Σ_s w*_s [(d*_s − d̂_s)² − V*_s]`` the replicates' quadratic noise, ``κ = (4 Σ_c L̂_c²
  − 4 wᵀ(Ĝ∘Ĝ)w) / θ̃`` (where positive; else the deviation spread as the noise, ``4 Σ w² V² /
  Σ w V``); ``boot_inv_floor``: its upper end at least the shipped power floor;
* ``null_inv_{zero,noise,linear}``: the same inversion with the plug-in's permutation null,
  centred, as the noise law and ``κ`` 0, the noise-shaped one, or as ``boot_inv``'s;
* ``lev_inv``: the same with session 24's ``r_inv`` ingredients around the shipped estimate:
  the plug-in under every assignment with each state's squared differences over ``1 − h``,
  centred, and ``κ`` from the pairs' linear variance with the weights ``w / (1 − h)``, less its
  noise (``_pairs_linear_variance``), over ``θ̃`` (the noise-shaped ``κ`` where not positive);

each interval's coverage of the true deviation (response_coverage_s14.json) with its misses
on each side, the replicates' sd over the sampling sd of ``θ̃``, and the variance parts: the
sampling variance of ``θ̃``, and the means of ``4 Σ_c L̂_c²``, ``4 wᵀ(Ĝ∘Ĝ)w``, the bootstrap's
variance, that of ``Q*`` and that of the plug-in's permutation null.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/deviation_excess_probe.py --pairs 160 \\
        --reps 100 --out benchmarks/results/deviation_excess_probe_160.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "scripts"))
import response_coverage  # noqa: E402
from deviation_calibrated_probe import (  # noqa: E402
    _pair_influences,
    _pairs_linear_variance,
    _per_pair,
    inverted_bounds,
    pair_leverage,
)
from deviation_world_probe import basic  # noqa: E402
from shift_refit_probe import LEVELS, RESPONSES, TRUTHS  # noqa: E402

import response_designs  # noqa: E402
from simcred.compare import conditional, effect  # noqa: E402
from simcred.compare.cluster_sums import MIN_UNITS, ClusterSums, Entries, normalised  # noqa: E402

REPLICATES = 500


def leverage_law(entries: Entries, keep: np.ndarray, assignments: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``lev_inv``'s noise law per response (J, P): the plug-in under every assignment with
    each state's squared differences over ``1 − h`` (``h = Σ_c (N_c / N)²`` over the pairs'
    transitions in the state), centred; and ``h`` per entering state."""
    h = pair_leverage(entries, keep)
    j = entries.first.shape[1]
    out = []
    for _, sides, total in effect.assignment_sides(entries, keep, assignments):
        w, mean_part, sd_part = effect.plugin_terms(sides, total, j)
        out.append((w * (mean_part + sd_part) / (1 - h)[:, None]).sum(axis=1))
    law = np.concatenate(out, axis=-1)[:, 1:]
    return law - law.mean(axis=1, keepdims=True), h


@dataclasses.dataclass(frozen=True)
class Sample:
    """One comparison's sums: per-pair sums (``_per_pair``), the units' totals and 500
    resampling weights with the sample's ones in column 0."""

    per_pair: np.ndarray
    totals: np.ndarray
    weights: np.ndarray
    sums: ClusterSums
    leverage: tuple[np.ndarray, np.ndarray]

    @classmethod
    def of(cls, data, design, rng, assignments: np.ndarray) -> Sample:
        entries = Entries.of(data, design)
        keep = entries.entering()
        take = keep[entries.state]
        n = entries.n_clusters
        return cls(_per_pair(entries, take, (np.cumsum(keep) - 1)[entries.state[take]]),
                   entries.totals(), np.hstack([np.ones((n, 1)),
                                                design.resamples(REPLICATES, rng)[:n]]),
                   ClusterSums.of(entries, keep), leverage_law(entries, keep, assignments))


def linear_parts(per_pair: np.ndarray, k: int, w: np.ndarray) -> tuple[float, float]:
    """``4 Σ_c L̂_c²`` and ``wᵀ(Ĝ∘Ĝ)w`` of response ``k`` (module docs)."""
    psi, difference = _pair_influences(per_pair, k)
    w2 = np.r_[w, w]
    gram = psi.T @ psi
    return 4 * float(((psi @ (w2 * difference))**2).sum()), float(w2 @ (gram * gram) @ w2)


def cross_variance(per_pair: np.ndarray, totals: np.ndarray, k: int, weights: np.ndarray
                   ) -> float:
    """``student_cross``'s variance of response ``k`` with the units counted ``weights`` times
    (that replicate's state weights, differences and influences)."""
    j = (len(per_pair) - 1) // 2
    sums = per_pair[[0, 1 + k, 1 + j + k]]  # N, S1, S2 per side, state, unit
    n, s1, s2 = (sums * weights).sum(axis=-1)
    usable = (((sums[0] > 0) & (weights > 0)).sum(axis=-1) >= MIN_UNITS).all(axis=0)
    total = totals.T @ weights
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = s1 / n
        var = np.maximum(s2 / n - mean**2, 0.0)
        psi_mean = (sums[1] - mean[..., None] * sums[0]) / n[..., None]
        psi_sd = (sums[2] - 2 * mean[..., None] * sums[1]
                  + (mean**2 - var)[..., None] * sums[0]) / (2 * np.sqrt(var) * n)[..., None]
        psi = np.nan_to_num(np.vstack([psi_mean[0] - psi_mean[1], psi_sd[0] - psi_sd[1]]),
                            posinf=0.0, neginf=0.0).T
        d = np.nan_to_num(np.r_[mean[0] - mean[1], np.sqrt(var[0]) - np.sqrt(var[1])])
    w2 = np.tile(normalised(np.where(usable, 0.5 * (n[0] / total[0] + n[1] / total[1]), 0.0)),
                 2)
    gram = (psi * weights[:, None]).T @ psi
    noise = float(w2 @ (gram * gram) @ w2)
    return max(4 * float((weights * (psi @ (w2 * d))**2).sum()) - 2 * noise, noise)


def _inverted(estimate: float, law: np.ndarray, kappa: float) -> list[tuple[float, float]]:
    found = inverted_bounds(estimate, law, kappa,
                            np.random.default_rng(7).standard_normal(10 * len(law)))
    return [(found[f"inv_{lv}_low"], found[f"inv_{lv}_high"]) for lv in LEVELS]


def _roots(bounds: list[tuple[float, float]]) -> list[tuple[float, float]]:
    return [tuple(float(np.sqrt(max(x, 0.0))) for x in pair) for pair in bounds]


def _student(estimate: float, scale: float, t: np.ndarray) -> list[tuple[float, float]]:
    out = []
    for lv in LEVELS:
        low, high = np.quantile(t, [(1 - lv) / 2, (1 + lv) / 2])
        out.append((estimate - scale * high, estimate - scale * low))
    return _roots(out)


def intervals(f, sample: Sample, k: int, cross: bool) -> dict:
    """Every interval (module docs) of one feature's shipped effect ``f``, per level."""
    c = sample.sums.components(sample.weights)[k]
    noise = c.var_mean + c.var_sd
    star = (c.w * (c.d_mean**2 + c.d_sd**2 - noise)).sum(axis=0)[1:]
    plugin, estimate = f.plugin**2, f.squared
    w = c.w[:, 0]
    four_l2, gg = linear_parts(sample.per_pair, k, w)
    spread = star.var(ddof=1)
    scale_k = float(np.sqrt(max(spread - 4 * gg, 0.0) / spread)) if spread > 0 else 1.0
    scaled = plugin + scale_k * (star - plugin)
    moved = dataclasses.replace(f, replicates=np.sign(scaled) * np.sqrt(np.abs(scaled)))
    se = np.sqrt(np.maximum((c.w**2 * (4 * (c.d_mean**2 - c.var_mean) * c.var_mean
                                       + 2 * c.var_mean**2 + 4 * (c.d_sd**2 - c.var_sd)
                                       * c.var_sd + 2 * c.var_sd**2)).sum(axis=0),
                            (c.w**2 * (c.var_mean**2 + c.var_sd**2)).sum(axis=0)))
    quad = (c.w[:, 1:] * ((c.d_mean[:, 1:] - c.d_mean[:, :1])**2
                          + (c.d_sd[:, 1:] - c.d_sd[:, :1])**2 - noise[:, 1:])).sum(axis=0)
    noise_kappa = 4 * float((w**2 * noise[:, 0]**2).sum()) / max(float((w * noise[:, 0]).sum()),
                                                                 1e-300)
    linear = four_l2 - 4 * gg
    kappa = linear / estimate if linear > 0 and estimate > 0 else noise_kappa
    boot_inv = _roots(_inverted(estimate, quad, kappa))
    out = {"k": scale_k, "boot_sd": float(np.sqrt(spread)), "squared": estimate,
           "parts": (four_l2, 4 * gg, spread, float(quad.var(ddof=1)),
                     float(f.null.var(ddof=1)) if len(f.null) > 1 else float("nan")),
           "shipped": [f.bounds((1 - lv) / 2) for lv in LEVELS],
           "scaled": basic(estimate, scaled, plugin),
           "scaled_shipped": [moved.bounds((1 - lv) / 2) for lv in LEVELS],
           "student": _student(estimate, se[0], (star - plugin) / se[1:]),
           "boot_inv": boot_inv,
           "boot_inv_floor": [(lo, max(hi, float(np.sqrt(f.power_floor((1 - lv) / 2)))))
                              for (lo, hi), lv in zip(boot_inv, LEVELS, strict=True)]}
    law, h = sample.leverage
    pairs = _pairs_linear_variance(sample.per_pair, w / (1 - h), k)
    out["lev_inv"] = _roots(_inverted(estimate, law[k], pairs / estimate
                                      if pairs > 0 and estimate > 0 else noise_kappa))
    centred = f.null - f.null.mean()
    for name, value in (("zero", 0.0), ("noise", noise_kappa), ("linear", kappa)):
        out[f"null_inv_{name}"] = _roots(_inverted(estimate, centred, value))
    if cross:
        variance = [cross_variance(sample.per_pair, sample.totals, k, sample.weights[:, r])
                    for r in range(sample.weights.shape[1])]
        out["student_cross"] = _student(estimate, np.sqrt(variance[0]),
                                        (star - plugin) / np.sqrt(variance[1:]))
    return out


def measure(kind: str, args) -> list[dict]:
    """Per replication, per response: :func:`intervals`."""
    shipped = effect.response_effects
    rows: list = []

    def both(data, design, *a, **kw):
        out = shipped(data, design, *a, **kw)
        sample = Sample.of(data, design, np.random.default_rng(len(rows)), a[6])
        rows.append({f.feature: intervals(f, sample, j, args.cross)
                     for j, f in enumerate(out.features) if f.feature in RESPONSES})
        return out

    conditional.response_effects = both
    for rep in range(args.seed0, args.seed0 + args.reps):
        response_coverage.effects(response_designs.defect(np.random.default_rng(rep), kind,
                                                          runs=args.pairs), rep, REPLICATES,
                                  permutations=args.permutations)
    conditional.response_effects = shipped
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--reps", type=int, default=100)
    parser.add_argument("--pairs", type=int, default=160)
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument("--permutations", type=int, default=199)
    parser.add_argument("--cross", action="store_true", help="also student_cross (slow)")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    truths = json.loads(TRUTHS.read_text())["table"]
    labels = ["shipped", "scaled", "scaled_shipped", "student", "boot_inv", "boot_inv_floor",
              "null_inv_zero", "null_inv_noise", "null_inv_linear", "lev_inv"] + (
        ["student_cross"] if args.cross else [])
    cells = {}
    for kind in args.kinds.split(","):
        rows = measure(kind, args)
        for name in RESPONSES:
            true = truths[kind][name]["truth"]
            spread = np.std([r[name]["squared"] for r in rows], ddof=1)
            cell = cells[f"{kind}/{name}"] = {
                "bootstrap_over_sampling": float(np.mean([r[name]["boot_sd"] for r in rows])
                                                 / spread),
                "scaled_over_sampling": float(np.mean([r[name]["boot_sd"] * r[name]["k"]
                                                       for r in rows]) / spread),
                "mean_k": float(np.mean([r[name]["k"] for r in rows])),
                "sampling_variance": float(spread**2)}
            cell |= dict(zip(("mean_4_sum_L2", "mean_4_wGGw", "mean_bootstrap_variance",
                              "mean_quadratic_noise_variance", "mean_null_variance"),
                             np.mean([r[name]["parts"] for r in rows], axis=0).tolist(),
                             strict=True))
            for label in labels:
                for i, lv in enumerate(LEVELS):
                    ends = np.array([r[name][label][i] for r in rows])
                    cell[f"{label}_{lv}"] = [float(np.mean((ends[:, 0] <= true)
                                                           & (true <= ends[:, 1]))),
                                             float(np.mean(ends[:, 0] > true)),
                                             float(np.mean(ends[:, 1] < true))]
            print(kind, name, json.dumps(cell), flush=True)
    if args.out:
        args.out.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                        "cells": cells}, indent=1) + "\n")


if __name__ == "__main__":
    main()
