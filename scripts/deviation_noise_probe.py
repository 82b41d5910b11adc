"""The response deviation's noise terms against their sampling values, and a test-inversion
interval tried against the shipped one (issue 21, interval coverage).

Per replication of a known-truth design (tests/response_designs.py ``defect``, paired, seeds 0
to ``--reps`` − 1) and response feature, from :meth:`ClusterSums.components` of the observed
data: the plug-in's two parts ``Σ w Δμ̂²`` and ``Σ w Δσ̂²`` and the noise ``θ̃`` subtracts from
each (``Σ w V̂_μ``, ``Σ w V̂_σ``: cluster variances, the delta method for the standard
deviation). Under the same law (kind ``none``) the plug-in is all noise, so the mean of each
part over the replications is the sampling noise its ``V̂`` should match.

Per class of units (on the side with fewer), the standard deviation's part against three
variances of its difference: shipped (delta method, pair covariance subtracted), without the
pair covariance, and without it but with the variance ``2 V̂_μ²`` of the quadratic term
``(μ̂ − μ)²`` of each side's ``v̂`` (:meth:`ClusterSums.components`).

``--coverage``: besides, the 90 % / 95 % coverage of the true squared deviation (TRUTH: the
values of benchmarks/results/response_coverage.json) by the shipped interval and by a
test-inversion interval with each of the three variances — ``X ~ N(δ, V)`` per state and
moment, ``δ`` allocated as the bias-corrected squares ``max(X² − V, 0)`` scaled to the
candidate ``θ``, the plug-in's law from 4,000 normal draws — and how often each would declare
equivalence at the true deviation (its one-sided 95 % upper bound below it: must be ≤ 0.05).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/deviation_noise_probe.py --coverage \
        --reps 200 --out benchmarks/results/deviation_noise_probe.json

``--per-state``: instead, per state code visited in most replications, the two standard
deviations' variances and covariance over the replications against the means of their
estimates (delta method, its second-order term, the members' covariance).

``--truth``: instead, the true deviation each noise correction defines (``√(mean θ̃)`` over
``--reps`` draws of ``--runs`` pairs, as response_coverage.py computes the shipped one).

``--crossfit K``: instead, a bias correction without variance estimates, against the shipped
one: the pairs split at random into two halves ``K`` times, each state's differences of means
and of standard deviations computed in each half, and ``θ`` estimated by the mean over the
splits of ``Σ w Δ⁽¹⁾ Δ⁽²⁾`` (the halves are independent, so a product has the square of the
halves' expected difference as its mean; the full sample's states and weights, renormalised
over the states both halves of a side visit).
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
from simcred.compare.cluster_sums import (  # noqa: E402
    ClusterSums,
    Entries,
    _pair_covariances,
    _side_moments,
)

RESPONSES = ("dv", "a")  # gap and v are kinematic consequences here (deviation ~1e-15)
#: The variances of the differences compared: (key in the terms, label).
ESTIMATES = (("v", "shipped"), ("v_nocov", "no_covariance"), ("v_second", "second_order"))
UNIT_CLASSES = (("2", 2, 2), ("3", 3, 3), ("4", 4, 4), ("5-6", 5, 6), ("7-10", 7, 10),
                ("11+", 11, 10**9))
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
        ones = np.ones((entries.n_clusters, 1))
        units = np.asarray(sums.visits.sum(axis=1)).reshape(-1, 2).min(axis=1)
        into.append({f.feature: (f, _terms(o, n, q, units)) for f, o, n, q in zip(
            out.features, sums.components(ones), sums.components(ones, pair_covariance=False),
            sums.components(ones, pair_covariance=False, second_order=True), strict=True)})
        return out
    return wrapped


def _terms(shipped, no_covariance, second, units) -> dict[str, np.ndarray]:
    """Per state and moment (means, then standard deviations): weight, difference and the
    shipped variances; the same with the standard deviation's variance without the pair
    members' covariance, and with the second-order term too (the mean's as shipped); per state
    the units of the side with fewer."""
    w = shipped.w[:, 0]
    return {"a": np.r_[w, w], "x": np.r_[shipped.d_mean[:, 0], shipped.d_sd[:, 0]],
            "v": np.r_[shipped.var_mean[:, 0], shipped.var_sd[:, 0]],
            "v_nocov": np.r_[shipped.var_mean[:, 0], no_covariance.var_sd[:, 0]],
            "v_second": np.r_[shipped.var_mean[:, 0], second.var_sd[:, 0]],
            "units": units}


def by_units(terms: list) -> dict[str, dict[str, float]]:
    """The standard-deviation part per class of units (on the side with fewer): its weight,
    ``Σ w Δσ̂²`` and each variance's share of it (1 = the noise matches, under the same law)."""
    out = {}
    for label, lo, hi in UNIT_CLASSES:
        rows = []
        for t in terms:
            half = len(t["a"]) // 2
            keep = (t["units"] >= lo) & (t["units"] <= hi) & (t["a"][:half] > 0)
            a = t["a"][half:][keep]
            rows.append([a.sum(), (a * t["x"][half:][keep]**2).sum()]
                        + [(a * t[v][half:][keep]).sum() for v, _ in ESTIMATES])
        weight, plugin, *noise = np.mean(rows, axis=0)
        if weight > 0.01:
            out[label] = {"weight": float(weight), "plugin_sd": float(plugin)} | {
                label: float(n / plugin) for (_, label), n in zip(ESTIMATES, noise, strict=True)}
    return out


def inverted(t: dict, level: float, rng, variance: str = "v") -> tuple[float, float]:
    """The test-inversion interval of θ (module docs) at ``level``, with the variances of
    ``variance`` (a key of :data:`ESTIMATES`)."""
    a, x, v = t["a"], t["x"], t[variance]
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


def bracketed(path: str) -> dict[str, dict[str, float]]:
    """True deviations with each correction's own same-law offset removed: per kind and
    response, the mean over the corrections of ``√(θ_kind − θ_none)`` (``--truth`` output)."""
    table = json.loads(Path(path).read_text())["table"]
    out = {}
    for kind, cells in table.items():
        if kind == "none":
            continue
        out[kind] = {name: float(np.mean([np.sqrt(max(
            cell[f"{label}_squared"] - table["none"][name][f"{label}_squared"], 0.0))
            for _, label in ESTIMATES])) for name, cell in cells.items()}
    return out


def crossfit_recording(into: list, splits: int):
    """``response_effects`` that also appends, per call and response, the shipped ``θ̃``'s two
    parts and the cross-fitted ones (module docs, ``--crossfit``)."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        sums = ClusterSums.of(entries, entries.entering())
        parts = sums.components(np.ones((entries.n_clusters, 1)))
        halves = np.random.default_rng(len(into)).permuted(
            np.arange(entries.n_clusters)[:, None].repeat(splits, axis=1), axis=0)
        first = (halves < entries.n_clusters // 2).astype(np.float64)
        get, count, inflate = sums.weighted(np.hstack([first, 1.0 - first]))
        row = {}
        for j, (f, c) in enumerate(zip(out.features, parts, strict=True)):
            w = c.w[:, 0]
            row[f.feature] = {"mean_shipped": float((w * (c.d_mean[:, 0]**2
                                                         - c.var_mean[:, 0])).sum()),
                              "sd_shipped": float((w * (c.d_sd[:, 0]**2
                                                       - c.var_sd[:, 0])).sum())}
            with np.errstate(invalid="ignore", divide="ignore"):
                a, b = (_side_moments(get, count[k], inflate[k], k, j) for k in (0, 1))
                for moment in ("mean", "sd"):
                    d = a[moment] - b[moment]
                    product = d[:, :splits] * d[:, splits:]
                    seen = np.isfinite(product)
                    weight = np.where(seen, w[:, None], 0.0)
                    weight /= weight.sum(axis=0)
                    row[f.feature][f"{moment}_crossfit"] = float(
                        (weight * np.where(seen, product, 0.0)).sum(axis=0).mean())
        into.append(row)
        return out
    return wrapped


def crossfit_summary(kind: str, rows: list, truth: dict) -> dict:
    """Per response, the mean (± its standard error) and the sampling sd over the replications
    of each correction's two parts and of their sum ``θ̃``, against the squared truth."""
    out = {}
    for name in RESPONSES:
        cell = {"truth_squared": truth.get(name, 0.0)**2}
        for method in ("shipped", "crossfit"):
            parts = {m: np.array([r[name][f"{m}_{method}"] for r in rows]) for m in ("mean", "sd")}
            for label, v in (parts | {"theta": parts["mean"] + parts["sd"]}).items():
                cell[f"{label}_{method}"] = float(v.mean())
                cell[f"{label}_{method}_se"] = float(v.std(ddof=1) / np.sqrt(len(v)))
                cell[f"{label}_{method}_sd"] = float(v.std(ddof=1))
        print(kind, name, json.dumps({k: round(v, 6) for k, v in cell.items()}), flush=True)
        out[name] = cell
    return out


def summary(kind: str, rows: list, coverage: bool, rng, other: dict | None = None) -> dict:
    """Noise terms per moment and class of units; with ``coverage``, each interval's coverage
    of the true deviation (and of ``other``, bracketed truths per response, if given), its
    misses low, and its equivalence declarations at the truth."""
    out = {}
    for name in RESPONSES:
        terms = [r[name][1] for r in rows]
        cell = {}
        for moment, part in (("mean", slice(None, None, 2)), ("sd", slice(1, None, 2))):
            for key, value in (("plugin", lambda t: t["x"]**2), ("noise", lambda t: t["v"]),
                               ("noise_second_order", lambda t: t["v_second"])):
                cell[f"{key}_{moment}"] = float(np.mean(
                    [(t["a"] * value(t)).reshape(2, -1)[part].sum() for t in terms]))
        if coverage:
            truths_here = {"": TRUTH[kind][name]} | ({"other_": other[name]} if other else {})
            for level in (0.90, 0.95):
                methods = {"shipped": [np.square(r[name][0].bounds((1 - level) / 2))
                                       for r in rows]}
                methods |= {f"inverted_{label}": [inverted(t, level, rng, variance)
                                                  for t in terms]
                            for variance, label in ESTIMATES}
                for method, bounds in methods.items():
                    for prefix, truth in truths_here.items():
                        t2 = truth**2
                        cell[f"{method}_{prefix}{level}"] = float(np.mean(
                            [lo <= t2 <= hi for lo, hi in bounds]))
                        cell[f"{method}_{prefix}low_above_{level}"] = float(np.mean(
                            [lo > t2 for lo, _ in bounds]))
                        if level == 0.90:  # its high end is the one-sided 95 % upper bound
                            cell[f"{method}_{prefix}equivalent_at_truth"] = float(np.mean(
                                [hi < t2 for _, hi in bounds]))
            if other:
                cell["other_truth"] = other[name]
        print(kind, name, json.dumps({k: round(v, 4) for k, v in cell.items()}), flush=True)
        cell["by_units"] = by_units(terms)
        print("  by units (sd part; variance / Σ w Δσ̂²):", json.dumps(
            {k: {m: round(x, 3) for m, x in v.items()} for k, v in cell["by_units"].items()}),
            flush=True)
        out[name] = cell
    return out


def per_state_recording(into: dict):
    """``response_effects`` that also appends, per entering state code and response, each
    side's standard deviation and its delta-method variance (first order, the second-order
    term), the members' covariance estimate and the units on the side with fewer."""
    shipped = effect.response_effects

    def wrapped(data, design, *args, **kwargs):
        out = shipped(data, design, *args, **kwargs)
        entries = Entries.of(data, design)
        keep = entries.entering()
        sums = ClusterSums.of(entries, keep)
        get, count, inflate = sums.weighted(np.ones((entries.n_clusters, 1)))
        units = np.asarray(sums.visits.sum(axis=1)).reshape(-1, 2).min(axis=1)
        codes = np.unique(data.state)[keep]
        for j, name in enumerate(f.feature for f in out.features):
            sides = [_side_moments(get, count[k], inflate[k], k, j) for k in (0, 1)]
            cov = _pair_covariances(get, count, inflate, *sides, j)[1][:, 0]
            a, b = ({key: value[:, 0] for key, value in m.items()} for m in sides)
            cov = cov / (4 * a["sd"] * b["sd"])
            for i, code in enumerate(codes):
                into.setdefault((name, int(code)), []).append(
                    [units[i]] + [m["sd"][i] for m in (a, b)]
                    + [m["var_v"][i] / (4 * m["sd"][i]**2) for m in (a, b)]
                    + [2 * m["var_mean"][i]**2 / (4 * m["sd"][i]**2) for m in (a, b)] + [cov[i]])
        return out
    return wrapped


def per_state(records: dict, reps: int) -> dict:
    """Per class of units: the standard deviations' variances and covariance over the
    replications of each state code visited in ≥ 60 % of them, against the means of the
    estimates (the states' edges move a little between replications: the empirical values
    are, if anything, too large)."""
    out = {}
    for name in RESPONSES:
        rows = []
        for (feature, _), values in records.items():
            v = np.array(values)
            if feature != name or len(v) < 0.6 * reps:
                continue
            empirical = np.cov(v[:, 1], v[:, 2])
            rows.append([np.median(v[:, 0]), empirical[0, 0] + empirical[1, 1],
                         empirical[0, 1], v[:, 3].mean() + v[:, 4].mean(),
                         v[:, 5].mean() + v[:, 6].mean(), v[:, 7].mean()])
        rows = np.array(rows)
        cell = {}
        for label, lo, hi in (("2-3", 2, 3), ("4-6", 4, 6), ("7+", 7, 10**9)):
            here = rows[(rows[:, 0] >= lo) & (rows[:, 0] <= hi)]
            if len(here):
                r = here.mean(axis=0)
                cell[label] = {"states": len(here), "variances": r[1], "covariance": r[2],
                               "variances_first_order": r[3], "second_order_term": r[4],
                               "covariance_estimate": r[5]}
        out[name] = cell
        print(name, "per state", json.dumps({k: {m: round(x, 6) for m, x in v.items()}
                                             for k, v in cell.items()}), flush=True)
    return out


def truths(kind: str, rows: list) -> dict:
    """Per response, ``√(mean θ̃)`` over the draws with each variance of :data:`ESTIMATES`
    (θ̃ = plug-in less the noise), with its standard error: the true deviation that each noise
    correction would define (``--truth``)."""
    out = {}
    for name in RESPONSES:
        cell = {}
        for variance, label in ESTIMATES:
            squared = [float((t["a"] * (t["x"]**2 - t[variance])).sum())
                       for t in (r[name][1] for r in rows)]
            mean = float(np.mean(squared))
            cell[label] = float(np.sqrt(max(mean, 0.0)))
            cell[f"{label}_squared"] = mean
            cell[f"{label}_squared_se"] = float(np.std(squared, ddof=1) / np.sqrt(len(rows)))
        out[name] = cell
        print(kind, name, "truth", json.dumps({k: round(v, 6) for k, v in cell.items()}),
              flush=True)
    return out


def replications(hook, kind: str, reps: int, runs: int, seed0: int, bootstrap: int,
                 **options) -> None:
    """Compare ``reps`` draws of the ``kind`` design (seeds ``seed0 + i``, ``runs`` pairs) with
    ``hook`` standing in for ``response_effects`` (it records what it measures); ``options``
    as :func:`response_coverage.effects` takes them."""
    effect_call = conditional.response_effects
    try:
        conditional.response_effects = hook
        for rep in range(reps):
            d = defect(np.random.default_rng(seed0 + rep), kind, runs=runs)
            response_coverage.effects(d, rep, bootstrap, **options)
    finally:
        conditional.response_effects = effect_call


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kinds", default="none,variance,delay,clip")
    parser.add_argument("--reps", type=int, default=80)
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--bootstrap", type=int, default=500)
    parser.add_argument("--coverage", action="store_true")
    parser.add_argument("--truth", action="store_true",
                        help="the true deviation under each noise correction instead: --reps "
                             "draws of --runs pairs, seeds 10**6 + i as response_coverage.py's")
    parser.add_argument("--per-state", action="store_true",
                        help="instead: per state code, the standard deviations' variances and "
                             "covariance over the replications against their estimates")
    parser.add_argument("--crossfit", type=int, default=0, metavar="K",
                        help="instead: the cross-fitted correction over K random halvings "
                             "against the shipped one (scored against --bracketed's truths)")
    parser.add_argument("--bracketed", default=None, metavar="TRUTH_JSON",
                        help="--coverage also scores every interval against the "
                             "bracketed truths of a --truth output (see bracketed())")
    parser.add_argument("--out", default="deviation_noise_probe.json")
    args = parser.parse_args(argv)
    table = {}
    other = bracketed(args.bracketed) if args.bracketed else {}
    for kind in args.kinds.split(","):
        rows: list = []
        records: dict = {}
        replications(per_state_recording(records) if args.per_state
                     else crossfit_recording(rows, args.crossfit) if args.crossfit
                     else recording(rows), kind, args.reps, args.runs,
                     10**6 if args.truth else 0, 2 if args.truth else args.bootstrap)
        if args.per_state:
            table[kind] = per_state(records, args.reps)
            continue
        if args.crossfit:
            table[kind] = crossfit_summary(kind, rows, other.get(kind, {}))
            continue
        table[kind] = truths(kind, rows) if args.truth else summary(
            kind, rows, args.coverage and kind != "none", np.random.default_rng(123),
            other.get(kind))
    Path(args.out).write_text(json.dumps({"args": vars(args), "table": table}, indent=1))


if __name__ == "__main__":
    main()
