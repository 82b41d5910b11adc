"""Known-truth study of `simcred validate` on car following (issue 22; docs/validate.md).

Designs (tests/validate_designs.py): a human-like IDM behind recorded OpenACC leader windows of
25 s at 0.1 s, the candidate replaying the same windows (paired by run), with

* ``none`` — the same model (truth: valid);
* ``delay_0.3`` / ``delay_0.5`` / ``delay_1.0`` — a reaction delay (truth: not valid);
* ``clip`` — applied acceleration clipped to [-1.5, +0.5] m/s² (truth: not valid);

and ``humans``: two random halves of the real OpenACC human episodes split by driver unit
(grouped by unit; truth: valid); ``acc_self``: one real ACC car (tests/validate_designs.py
ACC_CAR) against itself, its recording files split into two random halves (grouped by file;
truth: valid); ``leaders_split``: one deterministic IDM (tests/
response_designs.py, 10 s runs at 0.5 s) behind leaders of two different halves of the
recordings, unpaired (truth: valid — the same response law, other scenarios). Test case: the
whole leader-speed range, cells 0-15-30 m/s
(K = 2); features gap, v, v_leader with v_leader an input; tolerance on the acceleration response
(the rate of v): ``TOLERANCE`` = 0.012 m/s², the true deviation of a 0.15 s reaction delay
(scripts/validate_truth.py on 8,000 episodes per side: 0.0124 / 0.0112 in the two cells), so
every injected delay lies beyond it (0.022-0.233 m/s² in every cell), the clip is at it (0.0129
/ 0.0112) and the same model within.
A test case that tolerates a reaction-time error below 0.15 s.

For each candidate and size (episodes per side), ``--seeds`` draws; the counts of VALID /
NOT VALID / INCONCLUSIVE with the wrong verdicts (VALID for a not-valid truth, NOT VALID for a
valid one) and their Clopper-Pearson 95 % intervals. JSON with ``--out``.

Usage::

    OPENBLAS_NUM_THREADS=1 python scripts/validate_known_truth.py --seeds 200 \\
        --sizes 10 20 40 --out benchmarks/results/validate_known_truth_small.json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT / "tests"), str(ROOT / "examples" / "validate")]

from power import rate  # noqa: E402  (verdict counts as in examples/validate/power.py)

from response_designs import leaders_split  # noqa: E402
from simcred.validate.loop import Inputs, validate  # noqa: E402
from simcred.validate.spec import parse_validation  # noqa: E402
from validate_designs import acc_halves, closed_loop_pair, human_halves  # noqa: E402

TOLERANCE = 0.012  # m/s²: the acceleration-response deviation of a 0.15 s reaction delay
CANDIDATES = {"none": True, "delay_0.3": False, "delay_0.5": False, "delay_1.0": False,
              "clip": False, "humans": True, "leaders_split": True, "acc_self": True}


def spec(seed: int, *, design: str = "pairs", tolerance: float = TOLERANCE,
         bootstrap: int = 200, edges: tuple[float, ...] = (0, 15, 30)):
    """The study's validation (paths are placeholders: the sets go in through Inputs);
    ``design``: "pairs" (by run), "groups" (by driver unit), "files" (groups by recording
    file) or "runs" (unpaired runs)."""
    keys = {"pairs": {"pairs": {"by": "run_id"}}, "groups": {"groups": {"by": "unit"}},
            "files": {"groups": {"by": "file"}}, "runs": {}}
    return parse_validation({
        "test_case": {"conditions": f"{edges[0]} <= v_leader <= {edges[-1]}",
                      "tolerance": {"v": tolerance}},
        "reference": {"path": "-"}, "candidates": {"cand": {"runs": {"path": "-"}}},
        "features": ["gap", "v", "v_leader"], "inputs": ["v_leader"],
        **keys[design],
        "conditions": {"v_leader": {"unit": "m/s", "edges": list(edges)}},
        "comparison": {"bins": 3, "alpha": 0.05, "permutations": 99, "bootstrap": bootstrap,
                       "seed": seed},
        "min_data": {"runs": 4, "samples": 100}})


DESIGNS = {"humans": "groups", "leaders_split": "runs", "acc_self": "files"}


def draw(name: str, episodes: int, seed: int):
    rng = np.random.default_rng([seed, episodes, 22])
    if name == "humans":
        return human_halves(rng, episodes)
    if name == "acc_self":  # one real ACC car against itself, split by recording file
        return acc_halves(rng, episodes)
    if name == "leaders_split":  # one deterministic IDM behind leaders of different recordings
        found = leaders_split(rng, runs=episodes)
        return found.a, found.b
    return closed_loop_pair(rng, episodes, defect=name)


def verdict(name: str, episodes: int, seed: int, planned: bool = False, **options):
    reference, candidate = draw(name, episodes, seed)
    result = validate(spec(seed, design=DESIGNS.get(name, "pairs"), **options),
                      Inputs(reference, {"cand": candidate}, ()), planned=planned)
    return result


def plan_check(pilot: int, seeds: int, tolerance: float) -> dict:
    """The planned size from one draw at ``pilot`` episodes (the candidate's own pairs, searched
    by simulation), and VALID's rate at that size."""
    result = verdict("none", pilot, 10_000, planned=True, tolerance=tolerance)
    rows = [r for r in result.plan.rows if r.source == "cand"]
    searched = result.plan.candidates["cand"]
    found = {"pilot": pilot, "rows": [r.to_dict() for r in rows], "searched": searched.to_dict()}
    if not searched.sizes:
        return {**found, "planned": None}
    # the plan is in pairs per cell; a cell holds a share of the episodes' pairs
    now = {r.cell: r.units for r in rows}
    size = max(math.ceil(n * pilot / now[c]) for c, n in searched.sizes.items())
    print(f"plan from {pilot} episodes: {list(searched.sizes.values())} pairs in the cells (of "
          f"{list(now.values())} now; normal rule {[r.if_perfect for r in rows]}), simulated "
          f"power {searched.simulated_power:.2f} -> {size} episodes", flush=True)
    counts = Counter(verdict("none", size, seed, tolerance=tolerance).verdict
                     for seed in range(seeds))
    print(f"at {size} episodes: VALID {counts['valid']} / NOT VALID {counts['not valid']} / "
          f"INCONCLUSIVE {counts['inconclusive']} of {seeds}", flush=True)
    return {**found, "planned": size,
            "valid": rate(counts["valid"], seeds), "not_valid": rate(counts["not valid"], seeds),
            "inconclusive": rate(counts["inconclusive"], seeds)}


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--seeds", type=int, default=200)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--sizes", type=int, nargs="+", default=[10, 20, 40])
    parser.add_argument("--candidates", nargs="+", default=list(CANDIDATES))
    parser.add_argument("--tolerance", type=float, default=TOLERANCE)
    parser.add_argument("--edges", type=float, nargs="+", default=[0, 15, 30])
    parser.add_argument("--plan-from", type=int, default=None)
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    if args.plan_from is not None:
        found = plan_check(args.plan_from, args.seeds, args.tolerance)
        if args.out:
            Path(args.out).write_text(json.dumps({"tolerance": args.tolerance, **found},
                                                 indent=1))
        return
    rows = []
    print(f"{'candidate':>10} {'episodes':>8} {'truth':>9} {'VALID':>7} {'NOT VALID':>9} "
          f"{'INCONCL.':>8} {'wrong':>6} {'95 % CI':>13} {'s/draw':>7}")
    for episodes in args.sizes:
        for name in args.candidates:
            truly_valid = CANDIDATES[name]
            start = time.perf_counter()
            counts = Counter(verdict(name, episodes, seed, tolerance=args.tolerance,
                                     edges=tuple(args.edges)).verdict
                             for seed in range(args.first_seed, args.first_seed + args.seeds))
            seconds = (time.perf_counter() - start) / args.seeds
            wrong = counts["not valid"] if truly_valid else counts["valid"]
            row = {"candidate": name, "episodes": episodes, "seeds": args.seeds,
                   "first_seed": args.first_seed,
                   "truly_valid": truly_valid, "tolerance": args.tolerance,
                   **{k.replace(" ", "_"): rate(counts[k], args.seeds)
                      for k in ("valid", "not valid", "inconclusive")},
                   "wrong": rate(wrong, args.seeds), "seconds_per_draw": seconds}
            rows.append(row)
            low, high = row["wrong"]["ci95"]
            print(f"{name:>10} {episodes:>8} {'valid' if truly_valid else 'not valid':>9} "
                  f"{counts['valid']:>7} {counts['not valid']:>9} {counts['inconclusive']:>8} "
                  f"{wrong / args.seeds:>6.3f} {low:>6.3f}-{high:.3f} {seconds:>7.2f}",
                  flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps({"alpha": 0.05, "edges": args.edges,
                                              "tolerance": args.tolerance, "rows": rows},
                                             indent=1))


if __name__ == "__main__":
    main()
