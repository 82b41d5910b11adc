"""The "true" response deviation of each known-truth design of issue 22 (tests/validate_designs.py).

For each closed-loop defect (none, delay 0.15 / 0.3 / 0.5 / 1.0 s, clip; plus the crashing
±0.5 m/s² clip as a diagnostic) one LARGE paired draw (``--episodes`` per side, the same seed for
every defect: the same leader windows, reference and candidate noise, so the defects differ only
by the defect), compared as the study will compare it::

    compare(ref, cand, features=["gap", "v", "v_leader"], inputs=["v_leader"], test="response",
            pair_by="run_id", bins=3, permutations=19, bootstrap=50, seed=0)

over all samples and per leader-speed cell (v_leader in [0, 15) and [15, 30]: both sets cut into
maximal same-cell segments of >= 10 samples by simcred.validate.cells.segments, as a validation
grid would; the leader is the same in a pair, so the segments pair up by id). The estimate's
``estimate`` field (bias-corrected) is the truth; ``plugin`` and the 95 % interval are kept.
``delay_0.15`` is the study's tolerance ("a reaction-time error below 0.15 s is tolerated").

Then the truly valid ``none`` at growing sizes (its one-sided upper 95 % bound against the
tolerance), the real human halves (random halves of the OpenACC human-follower episodes by
unit, full size, ``group_by="unit"``): their deviation with its interval over several random
splits, and the per-episode cost of the simulation.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/validate_truth.py
    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/validate_truth.py --episodes 500 \
        --out /tmp/t.json
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
import validate_designs as vd  # noqa: E402
from simcred import __version__  # noqa: E402
from simcred.compare import compare  # noqa: E402
from simcred.traces import RUN_INFO, TraceSet  # noqa: E402
from simcred.validate.cells import grid_of, segments  # noqa: E402

FEATURES = ["gap", "v", "v_leader"]
INPUTS = ["v_leader"]
EDGES = [0.0, 15.0, 30.0]
MIN_LENGTH = 10
TOLERANCE = "delay_0.15"
STUDY = vd.DEFECTS
CHECKED = ("delay_0.3", "delay_0.5", "delay_1.0", "clip")  # must exceed the tolerance


def effect(a, b, args, **design) -> dict:
    """The response deviation per response feature (and the states it used)."""
    start = time.perf_counter()
    result = compare(a, b, features=FEATURES, inputs=INPUTS, test="response", bins=3,
                     permutations=args.permutations, bootstrap=args.bootstrap,
                     seed=args.compare_seed, **design)
    e = result.response.effect
    return {"runs": [a.n_runs, b.n_runs], "samples": [a.n_rows, b.n_rows], "states": e.states,
            "seconds": round(time.perf_counter() - start, 2),
            "pvalue": result.chain.pvalue,
            "features": {f.feature: {"unit": f.unit, "estimate": f.estimate, "plugin": f.plugin,
                                     "low": f.low, "high": f.high, "upper": f.upper,
                                     "upper_95": f.bounds(0.05)[1]}
                         for f in e.features}}


def with_parents(seg: TraceSet, whole: TraceSet) -> TraceSet:
    """Segments ``<run>@<row>`` with their parent run's facts and ``run`` = the parent's id."""
    info = whole.metadata[RUN_INFO]
    facts = {s: dict(info[s.rsplit("@", 1)[0]]) | {"run": s.rsplit("@", 1)[0]}
             for s in seg.run_ids}
    return TraceSet(seg.signals, seg.time, seg.values, seg.offsets, seg.run_ids,
                    dict(seg.metadata) | {RUN_INFO: facts}, seg.source)


def cells(a, b):
    """Per cell of the leader-speed grid: (label, segments of a, segments of b)."""
    grid = grid_of({"v_leader": SimpleNamespace(edges=EDGES, unit="m/s")})
    sa, sb = segments(a, grid, MIN_LENGTH), segments(b, grid, MIN_LENGTH)
    out = []
    for cell in range(grid.n_cells):
        if cell not in sa.by_cell or cell not in sb.by_cell:
            continue
        out.append((grid.label(cell), with_parents(sa.by_cell[cell], a),
                    with_parents(sb.by_cell[cell], b)))
    return out


def all_and_cells(a, b, args, **design) -> dict:
    """The deviation over all samples and per cell. Paired: a pair is a replayed run (whole
    runs; in a cell, all the run's segments there, ``pair_by="run"``); grouped: by the key."""
    out = {"all": effect(a, b, args, **design)}
    for label, ca, cb in cells(a, b):
        if design.get("pair_by") == "run_id":
            assert ca.run_ids == cb.run_ids, "paired segments must match (same leader)"
            out[label] = effect(ca, cb, args, pair_by="run")
        else:
            out[label] = effect(ca, cb, args, **design)
    return out


def closed_loop(args) -> dict:
    table = {}
    for defect in (*STUDY, *vd.DIAGNOSTIC):
        start = time.perf_counter()
        ref, cand = vd.closed_loop_pair(np.random.default_rng(args.seed), args.episodes,
                                        defect=defect)
        simulated = time.perf_counter() - start
        row = all_and_cells(ref, cand, args, pair_by="run_id")
        row["simulation_seconds"] = round(simulated, 2)
        row["crashed_runs"] = int(vd.crashed(cand).sum())
        row["min_gap"] = float(cand.column("gap").min())
        a = cand.column("a")
        row["candidate_a_at_clip"] = float(np.mean((a <= vd.CLIP[0] + 1e-12)
                                                  | (a >= vd.CLIP[1] - 1e-12)))
        if defect == "none":
            q = np.quantile(ref.column("a"), [0.001, 0.025, 0.975, 0.999])
            row["reference_a_quantiles"] = dict(zip(["0.1%", "2.5%", "97.5%", "99.9%"],
                                                    q.tolist(), strict=True))
            row["reference_v_leader_below_15"] = float(np.mean(ref.column("v_leader") < 15))
        table[defect] = row
        print_row(defect, row, flush=True)
    return table


def print_row(name, row, flush=False):
    parts = []
    for cell, r in row.items():
        if not isinstance(r, dict) or "features" not in r:
            continue
        f = r["features"]
        parts.append(f"{cell}: v {f['v']['estimate']:.4f} [{f['v']['low']:.4f}, "
                     f"{f['v']['high']:.4f}] gap {f['gap']['estimate']:.5f}")
    print(f"{name:11s} " + " | ".join(parts), flush=flush)


def checks(table) -> dict:
    """Monotone in the delay; every injected defect above the tolerance (estimate, and 95 %
    intervals separated), per feature and cell."""
    out = {}
    delays = ["none", *vd.DELAYS]
    for cell in table["none"]:
        if not isinstance(table["none"][cell], dict) or "features" not in table["none"][cell]:
            continue
        for feature in ("gap", "v"):
            est = {d: table[d][cell]["features"][feature] for d in table}
            seq = [est[d]["estimate"] for d in delays]
            tol = est[TOLERANCE]
            out[f"{cell} / {feature}"] = {
                "monotone_in_delay": bool(np.all(np.diff(seq) > 0)),
                "above_tolerance": {d: bool(est[d]["estimate"] > tol["estimate"])
                                    for d in CHECKED},
                "interval_above_tolerance_interval": {d: bool(est[d]["low"] > tol["high"])
                                                      for d in CHECKED},
            }
    return out


def tolerance_replicate(args) -> dict:
    """The tolerance's truth from an independent draw (seed + 1): how stable is it?"""
    ref, cand = vd.closed_loop_pair(np.random.default_rng(args.seed + 1), args.episodes,
                                    defect=TOLERANCE)
    return all_and_cells(ref, cand, args, pair_by="run_id")


def none_by_size(args, tolerance: dict) -> dict:
    """The truly valid candidate (``none``) at growing sizes: estimate and one-sided upper 95 %
    bound per feature and cell beside the tolerance (when could VALID be reached?)."""
    out = {}
    for n in args.none_sizes:
        row = all_and_cells(*vd.closed_loop_pair(np.random.default_rng(args.seed + 100 + n), n),
                            args, pair_by="run_id")
        for cell, r in row.items():
            for name, f in r["features"].items():
                f["upper_95_below_tolerance"] = bool(
                    f["upper_95"] < tolerance[cell]["features"][name]["estimate"])
        out[str(n)] = row
        print_row(f"none n={n}", row, flush=True)
    return out


def humans(args) -> dict:
    out = {"bootstrap": args.human_bootstrap, "splits": []}
    for split in range(args.human_splits):
        a, b = vd.human_halves(np.random.default_rng(split))
        units = [sorted({s.metadata[RUN_INFO][r]["unit"] for r in s.run_ids}) for s in (a, b)]
        hargs = SimpleNamespace(permutations=args.permutations, bootstrap=args.human_bootstrap,
                                compare_seed=args.compare_seed)
        row = all_and_cells(a, b, hargs, group_by="unit")
        row["seed"] = split
        row["units"] = units
        out["splits"].append(row)
        print_row(f"humans s{split}", row, flush=True)
    return out


def simulation_cost(args) -> dict:
    n = args.cost_episodes
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        vd.closed_loop_pair(np.random.default_rng(args.seed), n, defect="delay_0.15")
        best = min(best, time.perf_counter() - start)
    return {"episodes_per_side": n, "seconds": best, "ms_per_episode": 1000 * best / (2 * n),
            "episode_seconds": vd.WINDOW, "step": vd.DT}


def versions() -> dict:
    import scipy

    try:
        commit = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                                text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = None
    return {"simcred": __version__, "commit": commit, "numpy": np.__version__,
            "scipy": scipy.__version__, "python": platform.python_version(),
            "machine": platform.machine()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=8000, help="per side")
    parser.add_argument("--seed", type=int, default=0, help="data seed of the closed loop")
    parser.add_argument("--compare-seed", type=int, default=0)
    parser.add_argument("--permutations", type=int, default=19)
    parser.add_argument("--bootstrap", type=int, default=50)
    parser.add_argument("--human-bootstrap", type=int, default=500)
    parser.add_argument("--human-splits", type=int, default=10)
    parser.add_argument("--cost-episodes", type=int, default=2000)
    parser.add_argument("--none-sizes", type=lambda t: [int(x) for x in t.split(",")],
                        default=[10, 40, 300, 1000, 2000, 4000])
    parser.add_argument("--out", default=str(ROOT / "benchmarks/results/validate_truth.json"))
    args = parser.parse_args(argv)
    start = time.perf_counter()
    table = closed_loop(args)
    result = {
        "command": "scripts/validate_truth.py " + " ".join(argv if argv is not None
                                                            else sys.argv[1:]),
        "args": vars(args), "versions": versions(),
        "design": {"step": vd.DT, "window_seconds": vd.WINDOW, "phi": vd.PHI,
                   "noise_sd": float(vd.HUMAN.sigma), "noise_correlation_time": vd.TAU,
                   "headway": "1.5 exp(0.15 z) s per run", "start_headway": vd.T_NOMINAL,
                   "v_max": vd.V_MAX, "clip": list(vd.CLIP),
                   "clip_0.5": list(vd.CLIP_SYMMETRIC), "delays": vd.DELAYS,
                   "features": FEATURES, "inputs": INPUTS, "bins": 3, "cells": EDGES,
                   "segment_min_length": MIN_LENGTH},
        "closed_loop": table,
        "checks": checks({d: table[d] for d in STUDY}),
    }
    result["tolerance_replicate"] = tolerance_replicate(args)
    print_row("tol. seed+1", result["tolerance_replicate"])
    result["none_by_size"] = none_by_size(args, table[TOLERANCE])
    result["humans"] = humans(args)
    result["simulation_cost"] = simulation_cost(args)
    result["seconds"] = round(time.perf_counter() - start, 1)
    for key, value in result["checks"].items():
        print(key, json.dumps(value))
    print("simulation:", json.dumps(result["simulation_cost"]))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=1, ensure_ascii=False) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
