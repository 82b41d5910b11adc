"""Issue 21's equivalence acceptance, measured with the shipped code: a 0.5 s reaction delay and
20 car-following episodes.

Design (tests/response_designs.py :func:`defect`, kind ``delay``): A = the human-like stochastic
IDM behind recorded OpenACC leader windows (10 s episodes at 0.5 s, equilibrium starts); B =
the same driver whose IDM command uses the state 0.5 s (one step) earlier, replaying A's leader
windows (paired by ``run_id``, independent noise and headways). The comparison is the one a user
of car-following replays makes::

    compare(a, b, features=["gap", "v", "v_leader"], inputs=["v_leader"], test="response",
            pair_by="run_id", bins=4, alpha=0.05, permutations=999, bootstrap=500,
            margin={"v": 0.05})

(``scripts/response_coverage.py``'s :func:`effects`, with those features and inputs). The
margin is on the acceleration response of ``v`` (m/s²). Equivalence at δ is declared when the
one-sided upper 95 % bound ``upper`` lies below δ (effect.py); every δ is read from the same
bound (the API's own verdict at ``margin`` is checked against ``upper < margin``).

1. The true deviation of the delay: ``√(mean θ̃)`` over ``--truth-draws`` independent draws of
   ``--truth-runs`` pairs (:func:`response_coverage.truth`), ± its standard error; the same for
   the same-law control (kind ``none``).
2. ``--reps`` replications at ``--runs`` pairs (seeds ``seed0 + r``): the share declared
   equivalent at each δ of ``--margins`` and at δ = the true deviation (the boundary of H0:
   must be ≤ α = 0.05), with Wilson 95 % intervals; the mean and quantiles of the upper bound;
   the share of permutation p-values of the deviation below 0.05; coverage of the 95 % interval.
3. The same-law control (kind ``none``, seeds ``100000 + seed0 + r``) at the same size: share
   equivalent at the same δ and the upper bound's law (what margin 20 episodes can show at all).
4. Session 25, on the same draws: the bound without its power floor (``upper_bootstrap``,
   ``equivalent_bootstrap_bound_only``), the floor itself (``detectable``: the effect's
   ``floor``, 50 % power to first order), the share of draws it raised and the share in which an
   80 %-power floor would be above the bootstrap bound. ``--truth-from`` reuses the truths of an
   earlier output.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/equivalence_delay.py
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "scripts")]
from response_coverage import effects, truth  # noqa: E402

from response_designs import LEADER_FEATURES, defect  # noqa: E402
from simcred import __version__  # noqa: E402

FEATURE = "v"  # the margin's feature: the acceleration response (m/s²)
ALPHA = 0.05  # response_coverage.effects compares at alpha = 0.05
CONTROL_SEEDS = 100_000
QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)
OPTIONS = {"features": list(LEADER_FEATURES), "inputs": ["v_leader"]}


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score 95 % interval of a share k / n."""
    centre = (k + z * z / 2) / (n + z * z)
    half = z / (n + z * z) * math.sqrt(k * (n - k) / n + z * z / 4)
    return max(centre - half, 0.0), min(centre + half, 1.0)


def replicate(kind: str, seeds: range, args, margin: float) -> dict[str, np.ndarray]:
    """Per replication: the feature's estimate, one-sided upper and lower 95 % bounds, 95 %
    interval, permutation p-value and the API's equivalence verdict at ``margin``."""
    rows = {k: [] for k in ("estimate", "upper", "lower", "low", "high", "pvalue",
                            "equivalent_api", "detectable", "upper_bootstrap", "floor80")}
    options = OPTIONS | {"bins": args.bins, "permutations": args.permutations}
    for r, seed in enumerate(seeds):
        d = defect(np.random.default_rng(seed), kind, runs=args.runs)
        f = effects(d, seed, args.bootstrap, margin={FEATURE: margin}, **options)[FEATURE]
        assert f.equivalent == bool(f.upper < margin), (seed, f)
        for key in ("estimate", "upper", "lower", "low", "high", "pvalue"):
            rows[key].append(getattr(f, key))
        rows["detectable"].append(f.floor)  # the bound's floor: 50 % power to first order
        rows["equivalent_api"].append(f.equivalent)
        rows["upper_bootstrap"].append(replace(f, null=np.empty(0)).bounds(ALPHA)[1])
        high, low80 = np.quantile(f.null, [1 - ALPHA, 0.2]) if len(f.null) else (0.0, 0.0)
        rows["floor80"].append(float(np.sqrt(max(high - low80, 0.0))))
        if r + 1 in (5, 50) or (r + 1) % 200 == 0:
            print(f"  {kind}: {r + 1} replications", flush=True)
    return {k: np.asarray(v, dtype=float) for k, v in rows.items()}


def summary(rows: dict[str, np.ndarray], margins: dict[str, float], true: float | None
            ) -> dict:
    n = len(rows["upper"])
    upper = rows["upper"]
    out = {"replications": n, "equivalent": {}}
    for label, delta in margins.items():
        k = int((upper < delta).sum())
        out["equivalent"][label] = {"margin": delta, "count": k, "share": k / n,
                                    "wilson95": wilson(k, n)}
    out["equivalent_bootstrap_bound_only"] = {
        label: int((rows["upper_bootstrap"] < delta).sum()) for label, delta in margins.items()}
    out["floor_raises_bound_share"] = float(np.mean(upper > rows["upper_bootstrap"]))
    out["floor80_above_bootstrap_bound_share"] = float(
        np.mean(rows["floor80"] > rows["upper_bootstrap"]))
    out["detectable_quantiles"] = dict(zip(map(str, QUANTILES), np.quantile(
        rows["detectable"], QUANTILES).tolist(), strict=True))
    out["upper_mean"] = float(np.mean(upper))
    out["upper_quantiles"] = dict(zip(map(str, QUANTILES),
                                      np.quantile(upper, QUANTILES).tolist(), strict=True))
    out["estimate_mean"] = float(np.mean(rows["estimate"]))
    out["estimate_zero_share"] = float(np.mean(rows["estimate"] == 0))
    k = int((rows["pvalue"] < 0.05).sum())
    out["pvalue_below_0.05"] = {"count": k, "share": k / n, "wilson95": wilson(k, n)}
    out["lower_above_zero_share"] = float(np.mean(rows["lower"] > 0))
    if true is not None:
        out["coverage95"] = float(np.mean((rows["low"] <= true) & (true <= rows["high"])))
        out["upper_below_truth"] = float(np.mean(upper < true))
    out["per_replication"] = {k: np.round(rows[k], 6).tolist()
                              for k in ("estimate", "upper", "pvalue", "upper_bootstrap",
                                        "detectable")}
    return out


def print_table(table: dict) -> None:
    print(f"\n{'design':8s} {'δ [m/s²]':>16s} {'equivalent':>10s}   Wilson 95 %")
    for kind, row in table.items():
        for label, e in row["equivalent"].items():
            lo, hi = e["wilson95"]
            print(f"{kind:8s} {label:>16s} {e['count']:>5d}/{row['replications']:<4d}"
                  f"   {lo:.4f}–{hi:.4f}")
        q = row["upper_quantiles"]
        print(f"{kind:8s} upper bound mean {row['upper_mean']:.4f}, quantiles 5/25/50/75/95 % "
              + " / ".join(f"{v:.4f}" for v in q.values())
              + f"; mean estimate {row['estimate_mean']:.4f}; p < 0.05 in "
              f"{row['pvalue_below_0.05']['share']:.3f}"
              + (f"; 95 % coverage {row['coverage95']:.3f}" if "coverage95" in row else ""))


def finite(x):
    """``x`` with every NaN as None (strict JSON)."""
    if isinstance(x, dict):
        return {k: finite(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [finite(v) for v in x]
    return None if isinstance(x, float) and not math.isfinite(x) else x


def commit() -> str | None:
    try:
        return subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True,
                              text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return None


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--reps", type=int, default=1000)
    parser.add_argument("--runs", type=int, default=20, help="episode pairs per replication")
    parser.add_argument("--truth-runs", type=int, default=1500)
    parser.add_argument("--truth-draws", type=int, default=100)
    parser.add_argument("--control-truth-draws", type=int, default=50)
    parser.add_argument("--bins", type=int, default=4)
    parser.add_argument("--bootstrap", type=int, default=500)
    parser.add_argument("--permutations", type=int, default=999)
    parser.add_argument("--margins", default="0.012,0.025,0.05,0.075,0.1,0.15",
                        help="δ [m/s²] besides the true deviation")
    parser.add_argument("--seed0", type=int, default=0)
    parser.add_argument("--truth-from", metavar="JSON",
                        help="take the truths from an earlier run's output (same design)")
    parser.add_argument("--out", default=str(ROOT / "benchmarks/results/equivalence_delay.json"))
    args = parser.parse_args(argv)
    options = OPTIONS | {"bins": args.bins}
    start = time.time()
    truths = json.loads(Path(args.truth_from).read_text())["truth"] if args.truth_from else {}
    for kind, draws in (("delay", args.truth_draws), ("none", args.control_truth_draws)):
        if kind in truths:
            continue
        t = truth(kind, draws, args.truth_runs, **options)
        truths[kind] = {name: {"deviation": v[0], "deviation_se": v[1], "shift": v[2],
                               "shift_se": v[3]} for name, v in t.items()}
        print(f"truth {kind}: {FEATURE} {t[FEATURE][0]:.5f} ± {t[FEATURE][1]:.5f} m/s² "
              f"({draws} draws of {args.truth_runs} pairs, {time.time() - start:.0f} s)",
              flush=True)
    true = truths["delay"][FEATURE]["deviation"]
    margins = {f"{float(m):g}": float(m) for m in args.margins.split(",") if m}
    margins[f"truth {true:.4f}"] = true
    margins = dict(sorted(margins.items(), key=lambda kv: kv[1]))
    table = {}
    for kind, first, t in (("delay", args.seed0, true),
                           ("none", CONTROL_SEEDS + args.seed0, None)):
        rows = replicate(kind, range(first, first + args.reps), args, 0.05)
        table[kind] = summary(rows, margins, t)
        print(f"{kind}: {args.reps} replications, {time.time() - start:.0f} s", flush=True)
    print_table(table)
    out = {"args": vars(args) | {"out": Path(args.out).name}, "version": __version__,
           "commit": commit(),
           "seconds": round(time.time() - start, 1), "feature": FEATURE, "alpha": ALPHA,
           "comparison": {**options, "test": "response", "pair_by": "run_id", "alpha": ALPHA,
                          "permutations": args.permutations, "bootstrap": args.bootstrap,
                          "margin": {FEATURE: 0.05}},
           "truth": truths, "table": table}
    Path(args.out).write_text(json.dumps(finite(out), indent=1))
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
