"""Rejection rates of comparison methods on the known-truth designs of tests/response_designs.py.

For every selected design and replication r, one Design is drawn from a seed derived from the
design's name and r (the same data for every method), and every selected method returns a
p-value; a replication rejects when p <= alpha. Prints a markdown table (rejection rate with a
Wilson 95 % interval, errors, mean seconds per call) and the wall time of one draw of each design,
and writes everything to --out (JSON).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/response_bench.py --reps 200 \
        --designs h0 --methods energy,runs --out h0.json
    ... --designs 'defect:*:40:*' --reps 100

Design names: the H0 designs (``lengths``, ``lengths_markov``, ``paired_scenarios``,
``leaders_split``, ``grouped``, ``segments``), ``lengths_markov_equal10`` /
``lengths_markov_equal100`` (that chain with equal run lengths on both sides) and
``defect:<kind>:<runs>:<paired|unpaired>`` for
every kind of response_designs.DEFECTS and runs 40, 100. --designs takes comma-separated names or
shell patterns, and the aliases ``h0``, ``defects``, ``all``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # before numpy: many small matrices

import argparse  # noqa: E402
import fnmatch  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import zlib  # noqa: E402
from collections.abc import Callable  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from functools import partial  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from peer_energy import energy_test  # noqa: E402
from response_designs import DEFECTS, H0, Design, defect, lengths_markov  # noqa: E402
from simcred.compare import compare  # noqa: E402

# -- designs ---------------------------------------------------------------------------------------

DESIGNS: dict[str, Callable[[np.random.Generator], Design]] = dict(H0)
for _kind in DEFECTS:
    for _runs in (40, 100):
        for _paired in (True, False):
            DESIGNS[f"defect:{_kind}:{_runs}:{'paired' if _paired else 'unpaired'}"] = partial(
                defect, kind=_kind, runs=_runs, paired=_paired)
# the lengths_markov chain with equal run lengths (is the size problem the lengths' or the chain's?)
DESIGNS["lengths_markov_equal10"] = partial(lengths_markov, long=10)
DESIGNS["lengths_markov_equal100"] = partial(lengths_markov, short=100)
# does the excess of 10 vs 100 shrink with more runs (small-sample) or stay (structural)?
DESIGNS["lengths_markov_runs160"] = partial(lengths_markov, runs=160)
DESIGNS["lengths_markov_10vs30"] = partial(lengths_markov, long=30)
ALIASES = {"h0": list(H0), "defects": [n for n in DESIGNS if n.startswith("defect:")],
           "all": list(DESIGNS)}


def select(spec: str, known: list[str], aliases: dict[str, list[str]] | None = None) -> list[str]:
    out: list[str] = []
    for part in (p.strip() for p in spec.split(",") if p.strip()):
        names = (aliases or {}).get(part) or fnmatch.filter(known, part)
        if not names:
            raise SystemExit(f"unknown name or pattern {part!r}; known: {', '.join(known)}")
        out += [n for n in names if n not in out]
    return out


# -- methods: name -> callable(design, seed) -> p-value -------------------------------------------

#: Level and permutations of every method (set from the command line in each replication).
SETTINGS = {"alpha": 0.05, "permutations": 99}


def energy(d: Design, seed: int) -> float:
    """Peer: run-level energy distance on per-run summaries (knows no pairs/groups/inputs)."""
    return energy_test(d.a, d.b, d.features, permutations=SETTINGS["permutations"], seed=seed)


def runs(d: Design, seed: int) -> float:
    """Today's run-level chain test, bins 4."""
    return compare(d.a, d.b, features=list(d.features), test="runs",
                   permutations=SETTINGS["permutations"], seed=seed, alpha=SETTINGS["alpha"],
                   bins=4).chain.pvalue


def response(d: Design, seed: int) -> float:
    """The response test (test="response"), bins 4, with the design's inputs, pairs, groups."""
    return compare(d.a, d.b, features=list(d.features), test="response", inputs=d.inputs,
                   pair_by=d.pair_by, group_by=d.group_by,
                   permutations=SETTINGS["permutations"], seed=seed, alpha=SETTINGS["alpha"],
                   bins=4, bootstrap=20).chain.pvalue


METHODS: dict[str, Callable[[Design, int], float]] = {
    "energy": energy,
    "runs": runs,
    "response": response,
}


# -- one replication -------------------------------------------------------------------------------


def seeds(design: str, rep: int) -> tuple[np.random.Generator, int]:
    """Data rng and method seed of replication ``rep`` of ``design`` (stable across runs)."""
    ss = np.random.SeedSequence([zlib.crc32(design.encode()), rep])
    data, method = ss.spawn(2)
    return np.random.default_rng(data), int(method.generate_state(1)[0])


def replicate(design: str, rep: int, methods: list[str], alpha: float, permutations: int
              ) -> dict:
    SETTINGS.update(alpha=alpha, permutations=permutations)
    rng, seed = seeds(design, rep)
    t = time.perf_counter()
    d = DESIGNS[design](rng)
    out = {"design": design, "rep": rep, "draw_s": time.perf_counter() - t, "p": {}, "s": {},
           "error": {}}
    for m in methods:
        t = time.perf_counter()
        try:
            out["p"][m] = float(METHODS[m](d, seed))
        except Exception as exc:  # noqa: BLE001 - counted and reported, not fatal
            out["p"][m] = None
            out["error"][m] = f"{type(exc).__name__}: {exc}"[:300]
        out["s"][m] = time.perf_counter() - t
    return out


def _replicate_args(args: tuple) -> dict:
    return replicate(*args)


def wilson(k: int, n: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score 95 % interval of a binomial proportion."""
    if n == 0:
        return (math.nan, math.nan)
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def summarise(results: list[dict], designs: list[str], methods: list[str], alpha: float
              ) -> dict:
    table: dict = {}
    for name in designs:
        rows = [r for r in results if r["design"] == name]
        table[name] = {"reps": len(rows), "draw_s": float(np.mean([r["draw_s"] for r in rows])),
                       "methods": {}}
        for m in methods:
            ps = [r["p"][m] for r in rows if r["p"][m] is not None]
            k = int(sum(p <= alpha for p in ps))
            errors = [r["error"][m] for r in rows if m in r["error"]]
            table[name]["methods"][m] = {
                "rejected": k, "n": len(ps), "rate": k / len(ps) if ps else None,
                "ci95": wilson(k, len(ps)), "errors": len(errors),
                "first_error": errors[0] if errors else None,
                "seconds_per_call": float(np.mean([r["s"][m] for r in rows])),
            }
    return table


def markdown(table: dict, methods: list[str], alpha: float) -> str:
    lines = [f"rejection rate at α = {alpha} [Wilson 95 % interval]",
             "", "| design | reps | " + " | ".join(methods) + " |",
             "|---|---|" + "---|" * len(methods)]
    for name, row in table.items():
        cells = []
        for m in methods:
            c = row["methods"][m]
            if c["rate"] is None:
                cells.append(f"error ({c['first_error']})")
                continue
            cell = f"{c['rate']:.3f} [{c['ci95'][0]:.3f}, {c['ci95'][1]:.3f}]"
            if c["errors"]:
                cell += f" ({c['errors']} errors)"
            cells.append(cell)
        lines.append(f"| {name} | {row['reps']} | " + " | ".join(cells) + " |")
    lines += ["", "| design | draw (ms) | " + " | ".join(f"{m} (ms/call)" for m in methods) + " |",
              "|---|---|" + "---|" * len(methods)]
    for name, row in table.items():
        lines.append(f"| {name} | {1000 * row['draw_s']:.1f} | " + " | ".join(
            f"{1000 * row['methods'][m]['seconds_per_call']:.1f}" for m in methods) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--reps", type=int, default=200)
    parser.add_argument("--first-rep", type=int, default=0,
                        help="replications first-rep .. first-rep + reps - 1 (fresh seeds)")
    parser.add_argument("--designs", default="h0", help="names, patterns, or h0/defects/all")
    parser.add_argument("--methods", default=",".join(METHODS))
    parser.add_argument("--alpha", type=float, default=0.05)
    parser.add_argument("--permutations", type=int, default=99)
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--out", default="results.json")
    args = parser.parse_args(argv)
    designs = select(args.designs, list(DESIGNS), ALIASES)
    methods = select(args.methods, list(METHODS))

    # wall time of one draw of each design (after a warm-up draw has loaded and cut the
    # recordings: the first draw of a window length costs 0.1-0.4 s once per process)
    draw_ms = {}
    for name in designs:
        DESIGNS[name](np.random.default_rng(0))
        t = time.perf_counter()
        DESIGNS[name](np.random.default_rng(1))
        draw_ms[name] = 1000 * (time.perf_counter() - t)
        print(f"one draw of {name}: {draw_ms[name]:.1f} ms", flush=True)

    work = [(name, r, methods, args.alpha, args.permutations) for name in designs
            for r in range(args.first_rep, args.first_rep + args.reps)]
    t0 = time.perf_counter()
    if args.jobs > 1:
        with ProcessPoolExecutor(args.jobs) as pool:
            results = list(pool.map(_replicate_args, work, chunksize=16))
    else:
        results = [replicate(*w) for w in work]
    wall = time.perf_counter() - t0
    table = summarise(results, designs, methods, args.alpha)
    print(markdown(table, methods, args.alpha))
    print(f"\n{len(work)} replications in {wall:.1f} s ({args.jobs} processes)")
    out = {"alpha": args.alpha, "permutations": args.permutations, "reps": args.reps,
           "first_rep": args.first_rep,
           "methods": methods, "designs": designs, "draw_ms": draw_ms, "table": table,
           "wall_s": wall, "pvalues": {name: {m: [r["p"][m] for r in results
                                                  if r["design"] == name] for m in methods}
                                       for name in designs}}
    Path(args.out).write_text(json.dumps(out, indent=1))
    return out


if __name__ == "__main__":
    main()
