"""Does the entry rule make the shift's sampling spread smaller than its bootstrap's? (issue 21)

The cluster bootstrap holds the sample's entering states fixed (a state enters a replicate where
one drawn unit of each side visits it), while every real sample selects its own (≥ 2 units and
≥ 0.5 % of each side's transitions). On data where everything else is fixed or iid (the pooled
edges of one draw of 1,500 pairs, synthetic leaders, no global fit: scripts/shift_se_probe.py's
options), this compares two estimators over ``--reps`` replications of ``--pairs`` pairs: the
shipped shift (the sample's own entering states) and the shift over a FIXED set of states
(those that enter at 1,500 pairs, each present in a sample where one unit of each side visits
it, as in a bootstrap replicate) — each one's sampling standard deviation and its bootstrap's
(500 replicates) over it.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/shift_entry_probe.py --reps 200 \\
        --out benchmarks/results/shift_entry_probe.json
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
import shift_se_probe  # noqa: E402

import response_designs  # noqa: E402
from simcred.compare import conditional, effect, transitions  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402

RESPONSES = shift_se_probe.RESPONSES


def state_codes(data) -> np.ndarray:
    """The code of each distinct state, in the index order of ``Entries.of(data, ...)``."""
    return np.unique(data.state)


def shifts(data, design, keep: np.ndarray, rng: np.random.Generator, replicates: int = 500):
    """(features,) observed shift over ``keep`` and the bootstrap replicates' standard deviation."""
    entries = Entries.of(data, design)
    sums = ClusterSums.of(entries, keep)
    weights = design.resamples(replicates, rng)[:entries.n_clusters]
    every = sums.deviation(np.hstack([np.ones((entries.n_clusters, 1)), weights]))["shift"]
    return every[:, 0], every[:, 1:].std(axis=1, ddof=1)


def measure(kind: str, reps: int, pairs: int) -> tuple[list, int]:
    """Per replication of ``kind``, per response: (own shift, its bootstrap sd, fixed-states
    shift, its bootstrap sd); and the number of fixed states."""
    shipped = effect.response_effects
    population: dict = {}
    rows: list = []

    def remember(data, design, *a, **k):
        entries = Entries.of(data, design)
        population["codes"] = state_codes(data)[entries.entering()]
        return shipped(data, design, *a, **k)

    def both(data, design, *a, **k):
        entries = Entries.of(data, design)
        fixed = np.isin(state_codes(data), population["codes"])
        rng = np.random.default_rng(len(rows))
        own = shifts(data, design, entries.entering(), rng)
        pinned = shifts(data, design, fixed, rng)
        rows.append({n: (own[0][j], own[1][j], pinned[0][j], pinned[1][j])
                     for j, n in enumerate(data.response) if n in RESPONSES})
        return shipped(data, design, *a, **k)
    conditional.response_effects = remember
    shift_se_probe.population_edges(kind)  # its draw of 1,500 pairs passes through here
    conditional.response_effects = both
    for rep in range(reps):
        response_coverage.effects(response_designs.defect(np.random.default_rng(rep), kind,
                                                          runs=pairs), rep, 2)
    conditional.response_effects = shipped
    return rows, len(population["codes"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="clip_fixed,delay")
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--pairs", type=int, default=40)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    response_designs.draw_leaders = shift_se_probe.synthetic_leaders
    transitions.global_fit = shift_se_probe.centred
    result = {}
    for kind in args.kinds.split(","):
        rows, n_fixed = measure(kind, args.reps, args.pairs)
        for name in RESPONSES:
            x = np.array([r[name] for r in rows])
            own, pinned = x[:, 0].std(ddof=1), x[:, 2].std(ddof=1)
            cell = result[f"{kind}/{name}"] = {
                "own_states_sampling_sd": float(own),
                "own_states_bootstrap_over_sampling": float(x[:, 1].mean() / own),
                "fixed_states_sampling_sd": float(pinned),
                "fixed_states_bootstrap_over_sampling": float(x[:, 3].mean() / pinned),
                "fixed_states": n_fixed}
            print(kind, name, {k: round(v, 4) for k, v in cell.items()}, flush=True)
    if args.out:
        args.out.write_text(json.dumps({"reps": args.reps, "pairs": args.pairs, "bootstrap": 500,
                                        "cells": result}, indent=1) + "\n")


if __name__ == "__main__":
    main()
