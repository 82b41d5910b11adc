"""Is the calibrated deviation low at 40 pairs because of which states enter there? (issue 21,
interval coverage; tests/response_designs.py ``defect``, paired)

The state grid is held fixed at the pooled equal-frequency edges of one draw of
``--truth-runs`` pairs (seed 10**6, as the truths of response_coverage.py), so that a state is
the same cell in every sample. The population's per-state terms — each entering state's weight
``w_s`` and bias-corrected squared deviation ``θ_s`` (the shipped correction, whose truths agree
with the second-order one for ``a`` within 0.3 %), means over ``--truth-draws`` draws of
``--truth-runs`` pairs — give the truth over all the population's states, ``Σ w_s θ_s / Σ w_s``,
and, per replication at ``--runs`` pairs, the truth over the states that enter there (the same
sum over those states only). Against both: the calibrated estimate of
scripts/deviation_calibrated_probe.py and the shipped ``θ̃`` of the same replication.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/state_set_probe.py --reps 200 \\
        --out benchmarks/results/state_set_probe.json
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
from deviation_calibrated_probe import permutation_recording  # noqa: E402
from deviation_noise_probe import RESPONSES, replications  # noqa: E402

from response_designs import defect  # noqa: E402
from simcred.compare import effect, process  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402


def fixed_grid(kind: str, runs: int):
    """Hold every comparison's state space at the one of a draw of ``runs`` pairs (seed 10**6);
    returns the function that restores the shipped one."""
    shipped = process.common_space
    held: list = []

    def common_space(a, b, options):
        if not held:
            held.append(shipped(a, b, options))
        return held[0]

    process.common_space = common_space
    d = defect(np.random.default_rng(10**6), kind, runs=runs)
    response_coverage.effects(d, 0, 2)

    def restore():
        process.common_space = shipped
    return restore


def entering_codes(data, design) -> np.ndarray:
    return np.unique(data.state)[Entries.of(data, design).entering()]


def population_recording(into: list):
    """``response_effects`` that also appends, per call, each response's ``{code: (w_s, θ_s)}``
    over the entering states (the shipped per-state terms of :meth:`ClusterSums.components`)."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        keep = entries.entering()
        codes = np.unique(data.state)[keep]
        terms = ClusterSums.of(entries, keep).components(np.ones((entries.n_clusters, 1)))
        into.append({f.feature: {int(code): (float(c.w[i, 0]), float(
            c.d_mean[i, 0]**2 - c.var_mean[i, 0] + c.d_sd[i, 0]**2 - c.var_sd[i, 0]))
            for i, code in enumerate(codes)} for f, c in zip(out.features, terms, strict=True)})
        return out
    return wrapped


def with_codes(hook, codes: list):
    """``hook`` that also appends, per call, the entering state codes and their observed
    weights (the same for every response)."""
    def wrapped(data, design, *args, **kwargs):
        entries = Entries.of(data, design)
        keep = entries.entering()
        terms = ClusterSums.of(entries, keep).components(np.ones((entries.n_clusters, 1)))
        codes.append((np.unique(data.state)[keep], terms[0].w[:, 0]))
        return hook(data, design, *args, **kwargs)
    return wrapped


def population(draws: list) -> dict[str, dict[int, tuple[float, float]]]:
    """Per response, per state code: the mean weight and ``θ_s`` over the draws it entered."""
    out = {}
    for name in RESPONSES:
        found: dict = {}
        for draw in draws:
            for code, terms in draw[name].items():
                found.setdefault(code, []).append(terms)
        out[name] = {code: tuple(np.mean(v, axis=0)) for code, v in found.items()}
    return out


def restricted_truth(terms: dict[int, tuple[float, float]], codes, weights=None
                     ) -> tuple[float, float, float]:
    """``Σ w θ / Σ w`` over ``codes`` (those the population holds) with the population's
    weights, the population weight share they cover, and the same sum with the sample's own
    ``weights`` (NaN without)."""
    held = np.array([int(c) in terms for c in codes], dtype=bool)
    here = [terms[int(c)] for c in np.asarray(codes)[held]]
    total = sum(w for w, _ in terms.values())
    if not here:
        return float("nan"), 0.0, float("nan")
    w = np.array([h[0] for h in here])
    theta = np.array([h[1] for h in here])
    own = float("nan") if weights is None else float(
        (weights[held] * theta).sum() / weights[held].sum())
    return float((w * theta).sum() / w.sum()), float(w.sum() / total), own


def summary(kind: str, terms: dict, rows: list, codes: list) -> dict:
    out = {}
    for name in RESPONSES:
        full = restricted_truth(terms[name], list(terms[name]))[0]
        restricted = np.array([restricted_truth(terms[name], c, w) for c, w in codes])
        cell = {"truth_all_states": full, "population_states": len(terms[name]),
                "truth_sample_states": float(restricted[:, 0].mean()),
                "truth_sample_states_se": float(restricted[:, 0].std(ddof=1)
                                                / np.sqrt(len(codes))),
                "truth_sample_weights": float(restricted[:, 2].mean()),
                "truth_sample_weights_se": float(restricted[:, 2].std(ddof=1)
                                                 / np.sqrt(len(codes))),
                "weight_share_covered": float(restricted[:, 1].mean()),
                "sample_states": float(np.mean([len(c) for c, _ in codes]))}
        for method in ("shipped", "permutation_leverage"):
            v = np.array([r[name][method] for r in rows])
            cell[method] = float(v.mean())
            cell[f"{method}_se"] = float(v.std(ddof=1) / np.sqrt(len(v)))
        print(kind, name, json.dumps({k: round(v, 6) for k, v in cell.items()}), flush=True)
        out[name] = cell
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="variance,clip,delay")
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--truth-runs", type=int, default=1500)
    parser.add_argument("--truth-draws", type=int, default=10)
    parser.add_argument("--permutations", type=int, default=199)
    parser.add_argument("--out", default="state_set_probe.json")
    args = parser.parse_args(argv)
    table = {}
    for kind in args.kinds.split(","):
        restore = fixed_grid(kind, args.truth_runs)
        try:
            draws: list = []
            for i in range(args.truth_draws):
                replications(population_recording(draws), kind, 1, args.truth_runs,
                             10**6 + 1 + i, 2)
            terms = population(draws)
            rows, codes = [], []
            replications(with_codes(permutation_recording(rows), codes), kind, args.reps,
                         args.runs, 0, 2, permutations=args.permutations)
        finally:
            restore()
        table[kind] = summary(kind, terms, rows, codes)
    Path(args.out).write_text(json.dumps({"args": vars(args), "table": table}, indent=1))


if __name__ == "__main__":
    main()
