"""The shift's standard error against its sampling spread (issue 21, interval coverage): the
cluster bootstrap's (shipped) and a delete-one-cluster jackknife's (the same
:meth:`ClusterSums.deviation`, weights ``1 − e_c``), each divided by the standard deviation of
the shift over independent replications of the design (tests/response_designs.py ``defect``,
``--pairs`` paired runs, seeds 0 to ``--reps`` − 1, 500 bootstrap replicates).

``--synthetic-leaders``: every leader a fresh synthetic profile (speed 8-30 m/s, AR(1)
accelerations), an infinite population of independent scenarios, instead of one of the 56,509
overlapping windows of 50 recorded tracks. ``--no-fit``: the shift of the raw response (less
its pooled mean) instead of the response after the pooled global cubic fit, which every sample
estimates anew but the bootstrap holds fixed. ``--full B``: instead, per replication the spread of
the shift over ``B`` resamples of the pairs each compared anew (new pooled edges and states).
``--population-edges``: every sample's states on fixed edges, the pooled equal-frequency edges of
one draw of 1,500 pairs of the same design, instead of the sample's own (the bootstrap holds
the sample's edges fixed; this asks whether the adaptive edges are what makes the sampling
spread smaller than the bootstrap's). ``--smooth B``: also the spread of a Bayesian bootstrap
over ``B`` replicates (every pair weighted by an Exp(1) draw, so no state loses its visitors in
a replicate). ``--pairs``: the pairs per replication (default 40).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/shift_se_probe.py --reps 200 \\
        --out benchmarks/results/shift_se_probe.json
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

import response_designs  # noqa: E402
from simcred.compare import conditional, effect, transitions  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402
from simcred.compare.discretize import StateSpace  # noqa: E402
from simcred.traces import TraceSet  # noqa: E402

RESPONSES = ("dv", "a")  # gap and v are kinematic consequences here (shift ~1e-15)


def recording(into: list, smooth: int = 0):
    """``response_effects`` that also appends, per call, each response's (shift, bootstrap
    standard deviation, jackknife standard error[, the standard deviation over ``smooth``
    replicates of a Bayesian bootstrap: every cluster weighted by an Exp(1) draw, so that no
    state loses its visitors in a replicate])."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        keep = entries.entering()
        if keep.any():
            n = entries.n_clusters
            sums = ClusterSums.of(entries, keep)
            jack = sums.deviation(np.ones((n, n)) - np.eye(n))["shift"]
            se = np.sqrt((n - 1) / n * ((jack - jack.mean(axis=1, keepdims=True))**2).sum(axis=1))
            rows = [[f.shift, float(np.std(f.shift_replicates, ddof=1)), float(s)]
                    for f, s in zip(out.features, se, strict=True)]
            if smooth:
                rng = np.random.default_rng(len(into))
                drawn = sums.deviation(rng.exponential(size=(n, smooth)))["shift"]
                for row, spread in zip(rows, drawn.std(axis=1, ddof=1), strict=True):
                    row.append(float(spread))
            into.append({f.feature: tuple(row) for f, row in zip(out.features, rows,
                                                                  strict=True)})
        return out
    return wrapped


def synthetic_leaders(rng, runs, samples=response_designs.EPISODE, mask=None):
    """``runs`` independent synthetic leader windows (the fields of ``draw_leaders``)."""
    a = np.zeros((runs, samples))
    start = rng.uniform(8.0, 30.0, runs)
    for t in range(1, samples):
        a[:, t] = 0.8 * a[:, t - 1] + rng.normal(0.0, 0.4, runs)
    vl = np.maximum(start[:, None] + np.cumsum(a, axis=1) * 0.5, 0.0)
    track = np.arange(runs) % len(response_designs.tracks().info)  # metadata only
    return {"track": track, "start": np.zeros(runs, dtype=int), "v_leader": vl,
            "gap0": 2.0 + 1.5 * vl[:, 0], "v0": vl[:, 0], "mean_speed": vl.mean(axis=1),
            "file": np.array(["synthetic"] * runs)}


def centred(covariates: np.ndarray, rate: np.ndarray, *_) -> tuple[np.ndarray, None]:
    """``--no-fit``: the response less its pooled mean instead of its global cubic fit (the
    shift of a state is then the raw difference of the two sides' mean responses; no fit for
    the bootstrap to refit), in place of :func:`transitions.global_fit`."""
    return np.asfortranarray(rate - rate.mean(axis=0)), None


def full_resampling(d, seed: int, resamples: int) -> dict[str, tuple[float, float]]:
    """Per response, the observed shift and its standard deviation over ``resamples`` resamples
    of the pairs, each compared from scratch (edges, states, fits)."""
    def shift(a, b):
        return {f.feature: f.shift for f in response_coverage.effects(
            type(d)(a, b, d.features, pair_by="run_id"), seed, 2).values()}

    def take(traces, rows):
        return TraceSet.from_runs([traces.run(i) for i in rows],
                                  run_ids=[f"r{k}" for k in range(len(rows))])
    row_a = {r: i for i, r in enumerate(d.a.run_ids)}
    row_b = {r: i for i, r in enumerate(d.b.run_ids)}
    ids = sorted(row_a)
    rng = np.random.default_rng(10**7 + seed)
    draws = []
    for _ in range(resamples):
        pick = [ids[k] for k in rng.integers(0, len(ids), len(ids))]
        draws.append(shift(take(d.a, [row_a[r] for r in pick]),
                           take(d.b, [row_b[r] for r in pick])))
    observed = shift(d.a, d.b)
    return {n: (observed[n], float(np.std([x[n] for x in draws], ddof=1))) for n in RESPONSES}


SAMPLE_EDGES = StateSpace.__dict__["pooled"].__func__


def population_edges(kind: str, pairs: int = 1500) -> None:
    """Fix every later comparison's state edges at those of one draw of ``pairs`` pairs of
    ``kind`` (``--population-edges``; the first comparison after this call records them)."""
    fixed: dict = {}

    def recorded(cls, parts, bins, features):
        space = SAMPLE_EDGES(cls, parts, bins, features)
        edges = fixed.setdefault(tuple(features), space.edges)
        return StateSpace(space.features, edges, space.bounds)
    StateSpace.pooled = classmethod(recorded)
    response_coverage.effects(response_designs.defect(np.random.default_rng(10**6), kind,
                                                      runs=pairs), 0, 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="delay,variance,clip")
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--synthetic-leaders", action="store_true")
    parser.add_argument("--full", type=int, default=0, metavar="B")
    parser.add_argument("--no-fit", action="store_true")
    parser.add_argument("--population-edges", action="store_true")
    parser.add_argument("--smooth", type=int, default=0, metavar="B",
                        help="also a Bayesian bootstrap's spread over B replicates")
    parser.add_argument("--pairs", type=int, default=40)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    if args.synthetic_leaders:
        response_designs.draw_leaders = synthetic_leaders
    if args.no_fit:
        transitions.global_fit = centred
    shipped = conditional.response_effects
    result = {}
    for kind in args.kinds.split(","):
        found: list = []
        if args.population_edges:
            population_edges(kind)
        conditional.response_effects = shipped if args.full else recording(found, args.smooth)
        for rep in range(args.reps):
            d = response_designs.defect(np.random.default_rng(rep), kind, runs=args.pairs)
            if args.full:
                found.append(full_resampling(d, rep, args.full))
            else:
                response_coverage.effects(d, rep, 500)
        for name in RESPONSES:
            shift = np.array([r[name][0] for r in found])
            spread = float(shift.std(ddof=1))
            cell = result[f"{kind}/{name}"] = {"sampling_sd": spread}
            for k, label in enumerate(("full_resampling" if args.full else "bootstrap",
                                       *(() if args.full else ("jackknife",)),
                                       *(("smooth",) if args.smooth else ())), start=1):
                cell[f"{label}_over_sampling"] = float(
                    np.mean([r[name][k] for r in found]) / spread)
            print(kind, name, {k: round(v, 4) for k, v in result[f"{kind}/{name}"].items()},
                  flush=True)
    if args.out:
        args.out.write_text(json.dumps({"reps": args.reps, "pairs": args.pairs, "bootstrap": 500,
                                        "smooth": args.smooth,
                                        "full_resamples": args.full,
                                        "synthetic_leaders": args.synthetic_leaders,
                                        "no_fit": args.no_fit,
                                        "population_edges": args.population_edges,
                                        "cells": result}, indent=1) + "\n")


if __name__ == "__main__":
    main()
