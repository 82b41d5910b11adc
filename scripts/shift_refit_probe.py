"""The shift's bootstrap with the global fit estimated anew in every replicate (issue 21).

The shipped cluster bootstrap holds the pooled global cubic fit of the sample fixed: every
replicate takes the sample's residuals. Every real sample fits its own, and a regression
adjustment estimated on the sample can absorb part of that sample's between-pair variation
(scripts/shift_se_probe.py: at 160 pairs the clip design's excess bootstrap width goes with
synthetic leaders or without the fit). This probe refits the global fit in every replicate by
weighted least squares (each transition weighted by its cluster's multiplicity), recomputes the
residuals' sums over the sample's entering states and the replicate's shift, and reports each
bootstrap's standard deviation (refitted and fixed, the same replicate weights) over the shift's
sampling standard deviation over ``--reps`` replications of ``--pairs`` pairs; for the designs
of response_coverage_s14.json also each bootstrap's basic interval's coverage of the true shift,
and that of the refitted replicates moved to the fixed-fit replicates' median (the refit's
spread with the fixed fit's centring); and each bootstrap's median less the estimate, over the
sampling spread (mean over the replications).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/shift_refit_probe.py --kinds clip_fixed \\
        --pairs 160 --reps 150 --out benchmarks/results/shift_refit_probe_160.json
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
from shift_double_bootstrap_probe import bounds  # noqa: E402 (the basic interval)

import response_designs  # noqa: E402
from simcred.compare import conditional, effect, transitions  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402

RESPONSES = ("dv", "a")
LEVELS = (0.90, 0.95)
TRUTHS = ROOT / "benchmarks/results/response_coverage_s14.json"


def refitted_shifts(data, design, x: np.ndarray, y: np.ndarray, weights: np.ndarray
                    ) -> np.ndarray:
    """(features, replicates) shift of each replicate with the global fit weighted by it."""
    entries = Entries.of(data, design)
    keep = entries.entering()
    basis = transitions.Basis.of(x, True)
    if basis is None:
        raise SystemExit("the global fit is a mean here: nothing to refit")
    design_matrix = basis.design(x)
    cluster_of_row = data.unit % design.units_a if entries.pairs else data.unit
    out = np.empty((len(data.response), weights.shape[1]))
    for r in range(weights.shape[1]):
        root = np.sqrt(weights[cluster_of_row, r])[:, None]
        beta = np.linalg.lstsq(design_matrix * root, y * root, rcond=None)[0]
        level = np.asfortranarray(y - design_matrix @ beta)
        replicate = Entries.of(dataclasses.replace(data, level=level), design)
        out[:, r] = ClusterSums.of(replicate, keep).deviation(weights[:, r:r + 1])["shift"][:, 0]
    return out


def linearised_shifts(data, design, x: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(features, replicates) the fit's first-order part of each replicate's refitted shift,
    to be subtracted from the fixed-fit replicate: ``Σ_c w_rc a_c``, ``a_c = v' X_c' r_c``,
    ``v = G⁻¹ D_x`` (``G = X'X``, ``D_x`` the sample's shift of the basis columns); its mean
    over the replicates is 0 (normal equations)."""
    entries = Entries.of(data, design)
    keep = entries.entering()
    design_matrix = transitions.Basis.of(x, True).design(x)
    columns = Entries.of(dataclasses.replace(data, level=np.asfortranarray(design_matrix)),
                         design)
    d_x = ClusterSums.of(columns, keep).deviation(np.ones((entries.n_clusters, 1)))["shift"][:, 0]
    z = design_matrix @ np.linalg.solve(design_matrix.T @ design_matrix, d_x)
    cluster_of_row = data.unit % design.units_a if entries.pairs else data.unit
    a = np.stack([np.bincount(cluster_of_row, weights=z * r, minlength=entries.n_clusters)
                  for r in np.asarray(data.level).T])
    return a @ weights


def influence_shifts(sums: ClusterSums, n: int, weights: np.ndarray, eps: float = 1e-6
                     ) -> np.ndarray:
    """(features, replicates) the fixed-fit shift resampled linearly: ``θ̂ + Σ_c (w_rc − 1)
    ψ_c`` with ``ψ_c`` each cluster's influence (the derivative in its weight at the sample)."""
    base = sums.deviation(np.ones((n, 1)))["shift"]
    psi = (sums.deviation(np.ones((n, n)) + eps * np.eye(n))["shift"] - base) / eps
    return base + psi @ (weights - 1.0)


def measure(kind: str, reps: int, pairs: int, replicates: int, first_seed: int = 0,
            exact: bool = True) -> list[dict]:
    """Per replication: per response (shift, refitted bootstrap sd, fixed-fit bootstrap sd)."""
    shipped_fit, shipped = transitions.global_fit, effect.response_effects
    held: dict = {}
    rows: list = []

    def keeping(covariates, rate, *segments):
        held["x"], held["y"] = np.array(covariates), np.array(rate)
        return shipped_fit(covariates, rate, *segments)

    def both(data, design, *a, **k):
        entries = Entries.of(data, design)
        n = entries.n_clusters
        weights = design.resamples(replicates,
                                   np.random.default_rng(first_seed + len(rows)))[:n]
        fixed = ClusterSums.of(entries, entries.entering()).deviation(
            np.hstack([np.ones((n, 1)), weights]))["shift"]
        fit_part = linearised_shifts(data, design, held["x"], weights)
        linear = fixed[:, 1:] - fit_part
        sums = ClusterSums.of(entries, entries.entering())
        straight = influence_shifts(sums, n, weights) - fit_part
        refit = (refitted_shifts(data, design, held["x"], held["y"], weights) if exact
                 else linear)
        recentred = refit - np.median(refit, axis=1, keepdims=True) \
            + np.median(fixed[:, 1:], axis=1, keepdims=True)
        rows.append({name: (fixed[j, 0], refit[j].std(ddof=1), fixed[j, 1:].std(ddof=1),
                            *(bounds(fixed[j, 0], star, None, (1 - lv) / 2)
                              for star in (refit[j], fixed[j, 1:], recentred[j], linear[j],
                                           straight[j])
                              for lv in LEVELS),
                            np.median(refit[j]) - fixed[j, 0],
                            np.median(fixed[j, 1:]) - fixed[j, 0], straight[j].std(ddof=1),
                            linear[j].std(ddof=1))
                     for j, name in enumerate(data.response) if name in RESPONSES})
        return shipped(data, design, *a, **k)
    transitions.global_fit, conditional.response_effects = keeping, both
    for rep in range(first_seed, first_seed + reps):
        response_coverage.effects(response_designs.defect(np.random.default_rng(rep), kind,
                                                          runs=pairs), rep, 2)
    transitions.global_fit, conditional.response_effects = shipped_fit, shipped
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="clip_fixed,delay")
    parser.add_argument("--reps", type=int, default=150)
    parser.add_argument("--pairs", type=int, default=160)
    parser.add_argument("--replicates", type=int, default=200)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--no-exact", action="store_true",
                        help="skip the exact refit (its fields then repeat the linearised one)")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    result, truths = {}, json.loads(TRUTHS.read_text())["table"]
    for kind in args.kinds.split(","):
        rows = measure(kind, args.reps, args.pairs, args.replicates, args.first_seed,
                       not args.no_exact)
        for name in RESPONSES:
            x = np.array([r[name][:3] for r in rows])
            spread = x[:, 0].std(ddof=1)
            cell = result[f"{kind}/{name}"] = {
                "sampling_sd": float(spread),
                "refitted_bootstrap_over_sampling": float(x[:, 1].mean() / spread),
                "fixed_fit_bootstrap_over_sampling": float(x[:, 2].mean() / spread),
                "linearised_bootstrap_over_sampling": float(
                    np.mean([r[name][-1] for r in rows]) / spread),
                "influence_bootstrap_over_sampling": float(
                    np.mean([r[name][-2] for r in rows]) / spread),
                "refitted_median_offset_over_sampling": float(
                    np.mean([r[name][-4] for r in rows]) / spread),
                "fixed_fit_median_offset_over_sampling": float(
                    np.mean([r[name][-3] for r in rows]) / spread)}
            if kind in truths:
                true = truths[kind][name]["true_shift"]
                cell["mean_shift_less_truth_over_sampling"] = float((x[:, 0].mean() - true)
                                                                    / spread)
                for k, label in enumerate(("refitted", "fixed_fit", "refitted_recentred",
                                           "linearised", "influence")):
                    for i, lv in enumerate(LEVELS):
                        cell[f"{label}_coverage_{lv}"] = float(np.mean(
                            [lo <= true <= hi for lo, hi in (r[name][3 + 2 * k + i]
                                                             for r in rows)]))
            print(kind, name, {k: round(v, 4) for k, v in cell.items()}, flush=True)
    if args.out:
        args.out.write_text(json.dumps({"reps": args.reps, "pairs": args.pairs,
                                        "first_seed": args.first_seed,
                                        "replicates": args.replicates, "cells": result},
                                       indent=1) + "\n")


if __name__ == "__main__":
    main()
