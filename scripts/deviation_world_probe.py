"""The deviation's bootstrap from a world whose deviation is the estimate (issue 21, coverage).

scripts/deviation_width_probe.py found the bootstrap of ``θ̃`` 1.6–2.2× its sampling spread: the
bootstrap world's deviation is the plug-in ``θ̂``, which carries the noise, and the spread of a
squared difference grows with its noncentrality. This probe resamples instead a world moved to
the estimate: in every entering state B's transitions are mapped to the mean ``μ_A + λ (μ_B −
μ_A)`` and the standard deviation ``σ_A + λ (σ_B − σ_A)``, with one ``λ = √(max(θ̃, 0) / θ̂)``
per feature, so that the world's plug-in is about the estimate. (A ``λ`` per state and moment,
``√max(Δ̂² − V̂, 0) / |Δ̂|``, was tried first: clipping each state's term at 0 left the world's
plug-in 2.5× the estimate.) Per replication (``--pairs`` pairs of a
defect design, seeds from 0) it reports the shipped interval and the world's basic interval
``[θ̃ − (q_{1−a}(θ̃*) − T), θ̃ − (q_a(θ̃*) − T)]`` (``T`` the world's plug-in, bounds as roots,
clamped at 0): the replicates' sd over the sampling sd of ``θ̃`` and each interval's coverage of
the true deviation (response_coverage_s14.json); and the same with every replicate's noise
estimate replaced by the sample's (``held_noise``). Exploratory: no power floor, 200 replicates.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/deviation_world_probe.py --pairs 160 \\
        --reps 200 --out benchmarks/results/deviation_world_probe_160.json
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
from shift_refit_probe import LEVELS, RESPONSES, TRUTHS  # noqa: E402

import response_designs  # noqa: E402
from simcred.compare import conditional, effect  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402


def moved(data, design, entries: Entries, keep: np.ndarray) -> np.ndarray:
    """The residuals with B's transitions in every entering state moved (module docs)."""
    count = entries.count.astype(np.int64)
    state = np.repeat(entries.state, count)
    side = np.repeat(entries.side, count)
    observed = ClusterSums.of(entries, keep).deviation(np.ones((entries.n_clusters, 1)))
    with np.errstate(invalid="ignore", divide="ignore"):
        shrink = np.nan_to_num(np.sqrt(np.maximum(observed["squared"][:, 0], 0.0)
                                       / observed["plugin"][:, 0]))
    level = np.array(data.effect_residual, dtype=float, copy=True)
    for j in range(level.shape[1]):
        x = level[:, j]
        n = np.bincount(2 * state + side, minlength=2 * entries.n_states).reshape(-1, 2)
        s1 = np.bincount(2 * state + side, weights=x, minlength=2 * entries.n_states)
        s2 = np.bincount(2 * state + side, weights=x**2, minlength=2 * entries.n_states)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = s1.reshape(-1, 2) / n
            sd = np.sqrt(np.maximum(s2.reshape(-1, 2) / n - mean**2, 0.0))
        lam_mean = lam_sd = np.where(keep, shrink[j], 0.0)
        b = (side == 1) & keep[state]
        s = state[b]
        new_mean = mean[s, 0] + lam_mean[s] * (mean[s, 1] - mean[s, 0])
        new_sd = sd[s, 0] + lam_sd[s] * (sd[s, 1] - sd[s, 0])
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(sd[s, 1] > 0, new_sd / sd[s, 1], 1.0)
        x[b] = new_mean + scale * (x[b] - mean[s, 1])
    return np.asfortranarray(level)


def held_noise(sums: ClusterSums, weights: np.ndarray) -> np.ndarray:
    """(features, replicates) ``θ̃*`` with the sample's noise estimate in place of each
    replicate's own: ``Σ_s w*_s (Δμ*² + Δσ*² − V̂_μ,s − V̂_σ,s)``."""
    sample = sums.components(np.ones((weights.shape[0], 1)))
    out = []
    for c, c0 in zip(sums.components(weights), sample, strict=True):
        noise = (c0.var_mean + c0.var_sd)
        out.append((c.w * (c.d_mean**2 + c.d_sd**2 - noise)).sum(axis=0))
    return np.array(out)


def basic(estimate: float, star: np.ndarray, truth: float) -> list[tuple[float, float]]:
    """The basic interval at each of :data:`LEVELS` on the squared scale, as roots."""
    out = []
    for lv in LEVELS:
        a = (1 - lv) / 2
        lo = estimate - (np.quantile(star, 1 - a) - truth)
        hi = estimate - (np.quantile(star, a) - truth)
        out.append((np.sqrt(max(lo, 0.0)), np.sqrt(max(hi, 0.0))))
    return out


def measure(kind: str, reps: int, pairs: int) -> list[tuple[dict, dict]]:
    """Per replication: per response (θ̃, world replicates' sd, world plug-in, world bounds),
    and the shipped effects."""
    shipped = effect.response_effects
    rows: list = []

    def both(data, design, replicates, *a, **k):
        out = shipped(data, design, replicates, *a, **k)
        entries = Entries.of(data, design)
        keep = entries.entering()
        world = dataclasses.replace(data, level=moved(data, design, entries, keep))
        w_entries = Entries.of(world, design)
        n = entries.n_clusters
        weights = design.resamples(200, np.random.default_rng(len(rows)))[:n]
        sums = ClusterSums.of(w_entries, keep)
        every = sums.deviation(np.hstack([np.ones((n, 1)), weights]))
        held = held_noise(sums, weights)
        row = {}
        for j, name in enumerate(data.response):
            if name not in RESPONSES:
                continue
            f = next(x for x in out.features if x.feature == name)
            star, truth_w = every["squared"][j, 1:], every["plugin"][j, 0]
            row[name] = (f.squared, star.std(ddof=1), truth_w, basic(f.squared, star, truth_w),
                         held[j].std(ddof=1), basic(f.squared, held[j], truth_w))
        rows.append((row, {x.feature: x for x in out.features}))
        return out

    conditional.response_effects = both
    for rep in range(reps):
        response_coverage.effects(response_designs.defect(np.random.default_rng(rep), kind,
                                                          runs=pairs), rep, 500)
    conditional.response_effects = shipped
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--pairs", type=int, default=160)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    truths = json.loads(TRUTHS.read_text())["table"]
    cells = {}
    for kind in args.kinds.split(","):
        rows = measure(kind, args.reps, args.pairs)
        for name in RESPONSES:
            true = truths[kind][name]["truth"]
            x = np.array([r[name][:3] for r, _ in rows])
            spread = x[:, 0].std(ddof=1)
            cell = cells[f"{kind}/{name}"] = {
                "world_bootstrap_over_sampling": float(x[:, 1].mean() / spread),
                "mean_world_plugin_over_mean_estimate": float(x[:, 2].mean() / x[:, 0].mean())}
            cell["held_noise_bootstrap_over_sampling"] = float(
                np.mean([r[name][4] for r, _ in rows]) / spread)
            for i, lv in enumerate(LEVELS):
                for label, k in (("world", 3), ("held_noise", 5)):
                    cell[f"{label}_coverage_{lv}"] = float(np.mean(
                        [r[name][k][i][0] <= true <= r[name][k][i][1] for r, _ in rows]))
            cell["shipped_coverage_0.95"] = float(np.mean(
                [f[name].low <= true <= f[name].high for _, f in rows]))
            print(kind, name, {k: round(v, 4) for k, v in cell.items()}, flush=True)
    if args.out:
        args.out.write_text(json.dumps({"reps": args.reps, "pairs": args.pairs,
                                        "cells": cells}, indent=1) + "\n")


if __name__ == "__main__":
    main()
