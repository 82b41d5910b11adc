"""The deviation's bootstrap against its sampling law (issue 21, interval coverage).

The shipped deviation interval over-covers at 160 pairs (96–100 % at 90 %; docs/calibration.md
"Session 28"). Per replication of a paired defect design (tests/response_designs.py ``defect``,
``--pairs`` pairs, seeds ``--first-seed`` on, 500 bootstrap replicates) this records the
bias-corrected ``θ̃``, the plug-in ``θ̂`` and the bootstrap replicates ``θ̃*`` of the shipped
comparison (``FeatureEffect.replicates`` are their signed roots), and reports per response
feature: the sampling standard deviation of ``θ̃`` over the replications, the replicates'
mean standard deviation over it, and where the replicates sit — their median less ``θ̂`` (the
bootstrap world's truth, around which the basic bounds are taken) and less ``θ̃``, in sampling
standard deviations.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/deviation_width_probe.py --pairs 160 \\
        --reps 100 --out benchmarks/results/deviation_width_probe_160.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "scripts"))
import response_coverage  # noqa: E402
from shift_refit_probe import RESPONSES  # noqa: E402

import response_designs  # noqa: E402


def measure(kind: str, reps: int, pairs: int, first_seed: int) -> dict[str, np.ndarray]:
    """Per feature (replications, 4): θ̃, θ̂, the replicates' sd and median (squared scale)."""
    rows: dict[str, list] = {name: [] for name in RESPONSES}
    for seed in range(first_seed, first_seed + reps):
        effects = response_coverage.effects(
            response_designs.defect(np.random.default_rng(seed), kind, runs=pairs), seed, 500)
        for name in RESPONSES:
            f = effects[name]
            star = np.sign(f.replicates) * f.replicates**2
            rows[name].append((f.squared, f.plugin**2, star.std(ddof=1), np.median(star)))
    return {name: np.array(value) for name, value in rows.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--reps", type=int, default=100)
    parser.add_argument("--pairs", type=int, default=160)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    cells = {}
    for kind in args.kinds.split(","):
        for name, x in measure(kind, args.reps, args.pairs, args.first_seed).items():
            spread = x[:, 0].std(ddof=1)
            cell = cells[f"{kind}/{name}"] = {
                "sampling_sd_squared": float(spread),
                "mean_estimate_squared": float(x[:, 0].mean()),
                "mean_plugin_squared": float(x[:, 1].mean()),
                "bootstrap_over_sampling": float(x[:, 2].mean() / spread),
                "median_less_plugin_over_sampling": float(np.mean(x[:, 3] - x[:, 1]) / spread),
                "median_less_estimate_over_sampling": float(np.mean(x[:, 3] - x[:, 0]) / spread)}
            print(kind, name, {k: round(v, 4) for k, v in cell.items()}, flush=True)
    if args.out:
        args.out.write_text(json.dumps({"reps": args.reps, "pairs": args.pairs,
                                        "first_seed": args.first_seed, "cells": cells},
                                       indent=1) + "\n")


if __name__ == "__main__":
    main()
