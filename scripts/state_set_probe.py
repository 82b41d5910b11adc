"""Is the calibrated deviation low at 40 pairs because of which states enter there? (issue 21,
interval coverage; tests/response_designs.py ``defect``, paired)

The state grid is held fixed at the pooled equal-frequency edges of one draw of
``--truth-runs`` pairs (seed 10**6, as the truths of response_coverage.py), so that a state is
the same cell in every sample. The population's per-state terms — each entering state's weight
``w_s`` and its bias-corrected mean and standard-deviation parts (the shipped correction, whose
truths agree with the second-order one for ``a`` within 0.3 %; ``θ_s`` is their sum), means
over ``--truth-draws`` draws of ``--truth-runs`` pairs — give the truth over all the
population's states, ``Σ w_s θ_s / Σ w_s``, and, per replication at ``--runs`` pairs, the truth
over the states that enter there: with the population's weights, and with the sample's own
(then also per part). Against it, with the same weights: the calibrated estimate of
scripts/deviation_calibrated_probe.py, in total and per part.

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
from deviation_calibrated_probe import assignment_parts, calibrated_excess  # noqa: E402
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


def population_recording(into: list):
    """``response_effects`` that also appends, per call, each response's ``{code: (w_s, mean
    part, standard-deviation part)}`` over the entering states (the shipped per-state terms of
    :meth:`ClusterSums.components`, bias-corrected; ``θ_s`` is their sum)."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        keep = entries.entering()
        codes = np.unique(data.state)[keep]
        terms = ClusterSums.of(entries, keep).components(np.ones((entries.n_clusters, 1)))
        into.append({f.feature: {int(code): (
            float(c.w[i, 0]), float(c.d_mean[i, 0]**2 - c.var_mean[i, 0]),
            float(c.d_sd[i, 0]**2 - c.var_sd[i, 0])) for i, code in enumerate(codes)}
            for f, c in zip(out.features, terms, strict=True)})
        return out
    return wrapped


def calibrated_recording(into: list):
    """``response_effects`` that also appends, per call and response, the entering state codes,
    their observed weights, each one's calibrated mean and standard-deviation parts
    (scripts/deviation_calibrated_probe.py: the squared differences less their assignments'
    mean, over ``1 − h``; their weighted sum is its estimate) and per state the share of its
    visiting pairs that visit it with one member only."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        found = assignment_parts(data, design, args[6])
        codes = np.unique(data.state)[found.keep]
        into.append({f.feature: (codes, found.weight, calibrated_excess(
            found.parts[:2, k], found.entering[:, 1:])[0] / (1 - found.leverage),
            _one_sided(found.entries, found.keep)) for k, f in enumerate(out.features)})
        return out
    return wrapped


def _one_sided(entries: Entries, keep: np.ndarray) -> np.ndarray:
    """Per entering state, the share of the pairs visiting it whose other member does not."""
    take = keep[entries.state]
    state = (np.cumsum(keep) - 1)[entries.state[take]]
    sides = np.zeros((int(keep.sum()), entries.n_clusters, 2), dtype=bool)
    sides[state, entries.cluster[take], entries.side[take]] = True
    visiting = sides.any(axis=2).sum(axis=1)
    return (sides.any(axis=2) & ~sides.all(axis=2)).sum(axis=1) / np.maximum(visiting, 1)


def population(draws: list) -> dict[str, dict[int, np.ndarray]]:
    """Per response, per state code: the mean weight and parts over the draws it entered."""
    out = {}
    for name in RESPONSES:
        found: dict = {}
        for draw in draws:
            for code, terms in draw[name].items():
                found.setdefault(code, []).append(terms)
        out[name] = {code: np.mean(v, axis=0) for code, v in found.items()}
    return out


def one_sample(terms: dict[int, np.ndarray], codes, weight, parts, one_sided) -> np.ndarray:
    """For one sample's entering states (those the population holds): the population weight
    share they cover; the population's θ over them with its own weights; then with the
    sample's weights renormalised over them, the population's mean and sd parts and θ, and the
    calibrated mean and sd parts and θ; the share of the sample's weight they hold; the
    weighted share of their visiting pairs that visit with one member only."""
    held = np.array([int(c) in terms for c in codes], dtype=bool)
    pop = np.array([terms[int(c)] for c in np.asarray(codes)[held]]).reshape(-1, 3)
    total = sum(t[0] for t in terms.values())
    w = weight[held] / weight[held].sum()
    own = pop[:, 0] / pop[:, 0].sum()
    pop_parts = w @ pop[:, 1:]
    cal_parts = parts[:, held] @ w
    return np.array([pop[:, 0].sum() / total, own @ pop[:, 1:].sum(axis=1), *pop_parts,
                     pop_parts.sum(), *cal_parts, cal_parts.sum(),
                     weight[held].sum() / weight.sum(), w @ one_sided[held]])


FIELDS = ("weight_share_covered", "truth_sample_states", "truth_mean_part", "truth_sd_part",
          "truth_sample_weights", "calibrated_mean_part", "calibrated_sd_part", "calibrated",
          "sample_weight_held", "one_sided_pairs")


def summary(kind: str, terms: dict, rows: list) -> dict:
    out = {}
    for name in RESPONSES:
        pop = np.array(list(terms[name].values()))
        values = np.array([one_sample(terms[name], *r[name]) for r in rows])
        cell = {"truth_all_states": float(pop[:, 0] @ pop[:, 1:].sum(axis=1) / pop[:, 0].sum()),
                "population_states": len(pop),
                "sample_states": float(np.mean([len(r[name][0]) for r in rows]))}
        for k, field in enumerate(FIELDS):
            cell[field] = float(values[:, k].mean())
            cell[f"{field}_se"] = float(values[:, k].std(ddof=1) / np.sqrt(len(values)))
        print(kind, name, json.dumps({k: round(v, 6) for k, v in cell.items()}), flush=True)
        out[name] = cell
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="none,variance,delay,clip")
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
            rows: list = []
            replications(calibrated_recording(rows), kind, args.reps, args.runs, 0, 2,
                         permutations=args.permutations)
        finally:
            restore()
        table[kind] = summary(kind, terms, rows)
    Path(args.out).write_text(json.dumps({"args": vars(args), "table": table}, indent=1))


if __name__ == "__main__":
    main()
