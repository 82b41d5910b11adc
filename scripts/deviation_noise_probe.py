"""The response deviation's noise terms against their sampling values, and a test-inversion
interval tried against the shipped one (issue 21, interval coverage).

Per replication of a known-truth design (tests/response_designs.py ``defect``, paired, seeds 0
to ``--reps`` − 1) and response feature, from :meth:`ClusterSums.components` of the observed
data: the plug-in's two parts ``Σ w Δμ̂²`` and ``Σ w Δσ̂²`` and the noise ``θ̃`` subtracts from
each (``Σ w V̂_μ``, ``Σ w V̂_σ``: cluster variances, the delta method for the standard
deviation). Under the same law (kind ``none``) the plug-in is all noise, so the mean of each
part over the replications is the sampling noise its ``V̂`` should match.

``--coverage``: besides, the 90 % / 95 % coverage of the true squared deviation (TRUTH: the
values of benchmarks/results/response_coverage.json) by the shipped interval and by a
test-inversion interval — ``X ~ N(δ, V̂)`` per state and moment, ``δ`` allocated as the
bias-corrected squares ``max(X² − V̂, 0)`` scaled to the candidate ``θ``, the plug-in's law
from 4,000 normal draws — and how often each would declare equivalence at the true deviation
(its one-sided 95 % upper bound below it: must be ≤ 0.05).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/deviation_noise_probe.py --coverage \
        --reps 200 --out benchmarks/results/deviation_noise_probe.json
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

from response_designs import defect  # noqa: E402
from simcred.compare import conditional, effect  # noqa: E402
from simcred.compare.cluster_sums import ClusterSums, Entries  # noqa: E402

RESPONSES = ("dv", "a")  # gap and v are kinematic consequences here (deviation ~1e-15)
TRUTH = {"none": {"dv": 0.0, "a": 0.0},
         "variance": {"dv": 0.034591484297009735, "a": 0.07457864023300198},
         "delay": {"dv": 0.06260837378919096, "a": 0.04740284923211059},
         "clip": {"dv": 0.03863645153808854, "a": 0.07133976956823426}}


def recording(into: list):
    """``response_effects`` that also appends, per call, each response's observed terms."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        sums = ClusterSums.of(entries, entries.entering())
        observed = sums.components(np.ones((entries.n_clusters, 1)))
        into.append({f.feature: (f, {"a": np.r_[o.w[:, 0], o.w[:, 0]],
                                     "x": np.r_[o.d_mean[:, 0], o.d_sd[:, 0]],
                                     "v": np.r_[o.var_mean[:, 0], o.var_sd[:, 0]]})
                     for f, o in zip(out.features, observed, strict=True)})
        return out
    return wrapped


def inverted(t: dict, level: float, rng) -> tuple[float, float]:
    """The test-inversion interval of θ (module docs) at ``level``."""
    a, x, v = t["a"], t["x"], t["v"]
    observed = float((a * x**2).sum())
    share = np.maximum(x**2 - v, 0.0)
    share = share if (a * share).sum() > 0 else v.copy()
    direction = np.sign(x) * np.sqrt(share / max((a * share).sum(), 1e-300))
    noise = rng.standard_normal((4000, len(a))) * np.sqrt(v)
    cross, energy = noise @ (a * direction), (noise**2) @ a

    def above(theta):  # P(plug-in ≥ observed | θ): increasing in θ
        return float((theta + 2 * np.sqrt(theta) * cross + energy >= observed).mean())

    tail, top = (1 - level) / 2, 20 * observed + 10 * float((a * v).sum()) + 1e-12
    low = 0.0 if above(0.0) >= tail else _root(above, top, tail)
    high = 0.0 if above(0.0) >= 1 - tail else _root(above, top, 1 - tail)
    return low, high


def _root(f, top: float, target: float) -> float:
    lo, hi = 0.0, top
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) < target else (lo, mid)
    return 0.5 * (lo + hi)


def summary(kind: str, rows: list, coverage: bool, rng) -> dict:
    out = {}
    for name in RESPONSES:
        terms = [r[name][1] for r in rows]
        cell = {}
        for moment, part in (("mean", slice(None, None, 2)), ("sd", slice(1, None, 2))):
            for key, value in (("plugin", lambda t: t["x"]**2), ("noise", lambda t: t["v"])):
                cell[f"{key}_{moment}"] = float(np.mean(
                    [(t["a"] * value(t)).reshape(2, -1)[part].sum() for t in terms]))
        if coverage:
            truth = TRUTH[kind][name] ** 2
            for level in (0.90, 0.95):
                shipped = [r[name][0].bounds((1 - level) / 2) for r in rows]
                inverse = [inverted(t, level, rng) for t in terms]
                cell[f"shipped_{level}"] = float(np.mean([lo**2 <= truth <= hi**2
                                                          for lo, hi in shipped]))
                cell[f"inverted_{level}"] = float(np.mean([lo <= truth <= hi
                                                           for lo, hi in inverse]))
                cell[f"inverted_low_above_{level}"] = float(np.mean([lo > truth
                                                                     for lo, _ in inverse]))
            cell["inverted_equivalent_at_truth"] = float(np.mean(
                [inverted(t, 0.90, rng)[1] < truth for t in terms]))
            cell["shipped_equivalent_at_truth"] = float(np.mean(
                [r[name][0].upper < TRUTH[kind][name] for r in rows]))
        out[name] = cell
        print(kind, name, json.dumps({k: round(v, 4) for k, v in cell.items()}), flush=True)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="none,variance,delay,clip")
    parser.add_argument("--reps", type=int, default=80)
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--bootstrap", type=int, default=500)
    parser.add_argument("--coverage", action="store_true")
    parser.add_argument("--out", default="deviation_noise_probe.json")
    args = parser.parse_args(argv)
    table = {}
    for kind in args.kinds.split(","):
        rows: list = []
        effect_call = conditional.response_effects
        try:
            conditional.response_effects = recording(rows)
            for rep in range(args.reps):
                d = defect(np.random.default_rng(rep), kind, runs=args.runs)
                response_coverage.effects(d, rep, args.bootstrap)
        finally:
            conditional.response_effects = effect_call
        table[kind] = summary(kind, rows, args.coverage and kind != "none",
                              np.random.default_rng(123))
    Path(args.out).write_text(json.dumps({"args": vars(args), "table": table}, indent=1))


if __name__ == "__main__":
    main()
