"""The shift's basic bootstrap interval calibrated by a double bootstrap (issue 21, coverage).

The shipped shift interval is the basic cluster-bootstrap interval ``[2θ̂ − q_{1−a}(θ*),
2θ̂ − q_a(θ*)]``; at 40 pairs it over-covers (its bootstrap is 5–16 % wider than the sampling
spread; docs/calibration.md "Session 14"). Prepivoting (Beran 1987; Hall & Martin 1988) measures
that in the bootstrap world itself: for every outer replicate ``b`` (its estimate ``θ*_b``), an
inner bootstrap of ``b``'s own resample gives ``p_b = P**(θ** − θ*_b ≤ θ*_b − θ̂)``, whose law is
uniform where the basic interval is exact. The basic lower bound misses where ``p > 1 − a``, the
upper where ``p < a``; so the calibrated interval takes the outer quantiles at the levels the
``p_b`` say give the nominal miss rate::

    [2θ̂ − q_{Q_p(1−a)}(θ*),  2θ̂ − q_{Q_p(a)}(θ*)]

Stated before the runs: at 40 pairs (seeds 0–399) the calibrated interval's coverage is within
±3 points of 90 % and 95 % in all six cells of response_coverage.py's three defects, where the
basic one is 0.75–1.5 points above the 90 % band in one to two cells per seed set. The same
inner replicates also give a bootstrap-t interval (each outer replicate studentized by its
inner replicates' standard deviation), reported beside it.

Per replication the comparison runs as shipped (response_coverage.effects); a wrapper around
``response_effects`` rebuilds the same :class:`ClusterSums` and draws its own ``--outer`` outer
and ``--inner`` inner replicates per outer one (a seeded generator per replication), so the
basic interval of this probe is the shipped one up to its own bootstrap draws.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/shift_double_bootstrap_probe.py \\
        --reps 400 --out benchmarks/results/shift_double_bootstrap_probe.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "scripts"))
import response_coverage  # noqa: E402

import response_designs  # noqa: E402
from simcred.compare import conditional, effect  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402

RESPONSES = ("dv", "a")
LEVELS = (0.90, 0.95)


def inner_weights(outer: np.ndarray, inner: int, rng: np.random.Generator) -> np.ndarray:
    """(clusters, inner) multiplicities of resamples of the resample whose multiplicities are
    ``outer`` (n clusters drawn with replacement from its n drawn clusters)."""
    n = int(outer.sum())
    return rng.multinomial(n, outer / n, size=inner).T.astype(np.float64)


def calibrated(sums: ClusterSums, n: int, outer: int, inner: int, rng: np.random.Generator
               ) -> dict[str, dict]:
    """Per feature index: the observed shift, the outer replicates and the ``p_b``."""
    weights = rng.multinomial(n, np.full(n, 1.0 / n), size=outer).T.astype(np.float64)
    every = sums.deviation(np.hstack([np.ones((n, 1)), weights]))["shift"]
    observed, star = every[:, 0], every[:, 1:]
    p, spread = np.empty_like(star), np.empty_like(star)
    for b in range(outer):
        twice = sums.deviation(inner_weights(weights[:, b], inner, rng))["shift"]
        p[:, b] = (twice - star[:, b:b + 1] <= (star[:, b] - observed)[:, None]).mean(axis=1)
        spread[:, b] = twice.std(axis=1, ddof=1)
    return {"observed": observed, "star": star, "p": p, "spread": spread}


def bounds(observed: float, star: np.ndarray, p: np.ndarray | None, a: float
           ) -> tuple[float, float]:
    """The basic two-sided interval with ``a`` in each tail, calibrated by ``p`` if given."""
    lo_level, hi_level = (a, 1 - a) if p is None else (np.quantile(p, a), np.quantile(p, 1 - a))
    return (2 * observed - np.quantile(star, hi_level), 2 * observed - np.quantile(star, lo_level))


def studentized(observed: float, star: np.ndarray, spread: np.ndarray, a: float
                ) -> tuple[float, float]:
    """The bootstrap-t interval: ``t*_b = (θ*_b − θ̂) / s*_b`` with ``s*_b`` the inner
    replicates' standard deviation, scaled by the outer replicates' standard deviation."""
    t = (star - observed) / np.where(spread > 0, spread, np.nan)
    high, low = np.nanquantile(t, [1 - a, a])
    scale = star.std(ddof=1)
    return observed - high * scale, observed - low * scale


def recording(into: list, outer: int, inner: int):
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        keep = entries.entering()
        sums = ClusterSums.of(entries, keep)
        names = list(data.response)
        found = calibrated(sums, entries.n_clusters, outer, inner,
                           np.random.default_rng(7_000_000 + len(into)))
        into.append({name: (float(found["observed"][j]), found["star"][j], found["p"][j],
                            out.features[j].shift_bounds, found["spread"][j])
                     for j, name in enumerate(names) if name in RESPONSES})
        return out
    return wrapped


def score(found: list, truth: dict[str, float]) -> dict:
    cells = {}
    for name in RESPONSES:
        t, c = truth[name], {}
        for lv in LEVELS:
            a = (1 - lv) / 2
            rows = [(bounds(o, s, None, a), bounds(o, s, p, a), ship(a),
                     studentized(o, s, sd, a))
                    for o, s, p, ship, sd in (r[name] for r in found)]
            for k, label in enumerate(("basic", "calibrated", "shipped", "studentized")):
                c[f"{label}_{lv}"] = float(np.mean([lo <= t <= hi for lo, hi in
                                                    (row[k] for row in rows)]))
                c[f"{label}_{lv}_low_above"] = float(np.mean([row[k][0] > t for row in rows]))
        p = np.concatenate([r[name][2] for r in found])
        c["p_quantiles_05_50_95"] = [float(x) for x in np.quantile(p, [0.05, 0.5, 0.95])]
        cells[name] = c
    return cells


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="variance,delay,clip")
    parser.add_argument("--reps", type=int, default=400)
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument("--pairs", type=int, default=40)
    parser.add_argument("--outer", type=int, default=500)
    parser.add_argument("--inner", type=int, default=100)
    parser.add_argument("--truth-from", type=Path,
                        default=ROOT / "benchmarks/results/response_coverage_s14.json")
    parser.add_argument("--out", type=Path)
    args = parser.parse_args()
    truths = json.loads(args.truth_from.read_text())["table"]
    shipped = conditional.response_effects
    result = {}
    for kind in args.kinds.split(","):
        start, found = time.time(), []
        conditional.response_effects = recording(found, args.outer, args.inner)
        for rep in range(args.seed0, args.seed0 + args.reps):
            d = response_designs.defect(np.random.default_rng(rep), kind, runs=args.pairs)
            response_coverage.effects(d, rep, 500)
        conditional.response_effects = shipped
        result[kind] = score(found, {n: truths[kind][n]["true_shift"] for n in RESPONSES})
        print(kind, f"{time.time() - start:.0f}s", json.dumps(result[kind]), flush=True)
    if args.out:
        args.out.write_text(json.dumps({"args": {k: str(v) for k, v in vars(args).items()},
                                        "cells": result}, indent=1) + "\n")


if __name__ == "__main__":
    main()
