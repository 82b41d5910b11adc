"""Benchmarks of the contracts: prints tables, writes benchmarks/results/contracts.json.

(a) configuring an architecture of 8 components × 4 candidate models (a chain of interval
    contracts, seeded), with the optimum proven by the search and checked against the cheapest
    setup found by exhaustive enumeration of all 4⁸ = 65,536 setups (enumeration is done with the
    closed form of interval chains, not with z3, so that it finishes); the CEGIS search over z3
    (the method before the interval search) is timed on the same libraries;
(c) configuring 12 components × 4–6 models (≥ 20 M setups) in a seeded DAG of interval
    contracts, 5 libraries: the interval branch-and-bound against exhaustive enumeration of every
    setup, vectorised with numpy (the closed form of interval propagation), in the same run:
    same optimum, and the speed-up (target ≥ 10×);
(b) monitors: samples per second on invariant clauses over 10⁷ samples, against a hand-written
    numpy expression of the same clauses in the same run;
(f) configuration of generated libraries (benchmarks/contract_libraries.py: non-convex chains
    20 × 6 and 30 × 8, fan-in 10 × 4 and 20 × 6): the path configure takes (0-1 optimisation)
    against the generator's independent optimum, and the counterexample-guided path (the method
    before issue 28) in the same run, stopped after CEGIS_LIMIT_S seconds;
(g) ``contracts quotient`` on a chain of n interval contracts (benchmarks/contract_libraries.py
    ``chain(n, 3, 1)``), the cheapest valid setup given except the middle component (19 given
    models at n = 20): the requirement (quotient, projection, readable text, uncovered
    assumptions) with the projection by ``qe_rec`` against the classic ``qe`` (the path before,
    which gives up after its 10 s limit and prints the unprojected quotient) in the same run,
    the quotient's size in AST nodes (linear in the models) and the whole CLI command; also a
    chain of 30, and (not --quick) one component missing from the configured setups of the
    generated non-convex and fan-in libraries (f) and the DAG of (c);
(e) ``until`` over 10⁶ samples at 100 Hz with a 10 s window (1,000 samples), the block
    decomposition against the loop over window offsets (the method before issue 28) on 10⁵
    samples of the same signal, in samples per second (target: 10⁶ samples < 2 s); the same on
    10⁶ non-uniformly sampled time stamps (steps uniform in 5–15 ms), where the clamp levels
    replace the loop over window offsets (the path there before).
Usage: python benchmarks/contracts.py [--quick] [--only SECTION ...]
(``--only`` writes benchmarks/results/contracts-SECTION….json, leaving contracts.json alone.)
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from _timing import best_of, machine  # noqa: E402
from contract_libraries import chain as chain_library  # noqa: E402

from simcred.contracts.algebra import Contract  # noqa: E402
from simcred.contracts.configure import configure  # noqa: E402
from simcred.contracts.library import Library  # noqa: E402
from simcred.contracts.monitor import monitor  # noqa: E402
from simcred.traces import TraceSet  # noqa: E402


def cheapest_by_enumeration(table, input_hi: int = 10, final: int = 9):
    """Closed form of a chain of interval contracts: valid iff every model's domain contains the
    previous bound (the test case's input range first) and the last output is within ``final``."""
    best = None
    for choice in itertools.product(*table):
        bound, ok = input_hi, True
        for _, hi, out, _ in choice:
            if bound > hi:
                ok = False
                break
            bound = out
        if ok and bound <= final:
            cost = sum(c for *_, c in choice)
            if best is None or cost < best[0] - 1e-9:
                best = (cost, [m for m, *_ in choice])
    return best


def bench_configuration(seeds) -> list[dict]:
    rows = []
    for seed in seeds:
        lib, table = chain_library(8, 4, seed)
        seconds, result = best_of(lambda lib=lib: configure(lib, "tc"), 3)
        cegis_seconds, cegis = best_of(lambda lib=lib: configure(lib, "tc", search="cegis"), 1)
        brute_seconds, best = best_of(lambda table=table: cheapest_by_enumeration(table), 1)
        rows.append({"case": f"(a) 8 components × 4 models, seed {seed}", "seconds": seconds,
                     "status": result.status.value, "cost": result.cost,
                     "optimum_by_enumeration": None if best is None else best[0],
                     "optimal": (best is None and result.cost is None)
                     or (best is not None and result.cost is not None
                         and abs(result.cost - best[0]) < 1e-6),
                     "candidates_checked": result.iterations, "setups": 4 ** 8,
                     "enumeration_seconds": brute_seconds, "cegis_seconds": cegis_seconds,
                     "cegis_cost": cegis.cost, "speedup_vs_cegis": cegis_seconds / seconds})
    return rows


def dag_library(seed: int, components: int = 12, min_setups: int = 20_000_000):
    """A seeded DAG: three environment variables e0..e2 in [0, 10]; component k reads one or two
    of the environment variables and earlier outputs and drives y_k; each model assumes
    0 <= x <= hi on its inputs and guarantees 0 <= y_k <= out; wider domains and tighter outputs
    cost more. The test case bounds the last output and one other."""
    rng = np.random.default_rng(seed)
    while True:
        sizes = rng.integers(4, 7, components)
        if min_setups <= np.prod(sizes.astype(object)) <= 3 * min_setups:
            break
    spec = {"variables": {**{f"e{j}": {"unit": "m"} for j in range(3)},
                          **{f"y{k}": {"unit": "m"} for k in range(components)}},
            "components": {}, "models": {}, "architecture": []}
    sources, table = [f"e{j}" for j in range(3)], []
    for k in range(components):
        pool = sources[-5:]
        inputs = sorted(set(rng.choice(pool, size=int(rng.integers(1, 3)), replace=True)))
        spec["components"][f"C{k}"] = {"inputs": inputs, "outputs": [f"y{k}"]}
        spec["architecture"].append(f"C{k}")
        row = []
        for j in range(int(sizes[k])):
            his = {x: int(rng.integers(8, 16)) for x in inputs}
            out = int(rng.integers(4, 12))
            cost = round(10 + 0.5 * (sum(his.values()) / len(his) - out) + rng.uniform(0, 3), 2)
            spec["models"][f"M{k}_{j}"] = {
                "implements": f"C{k}", "cost": cost,
                "contract": {"assumption": " and ".join(f"0 <= {x} <= {h}"
                                                        for x, h in his.items()),
                             "guarantee": f"0 <= y{k} <= {out}"}}
            row.append((his, out, cost))
        table.append((inputs, row))
        sources.append(f"y{k}")
    goal = {f"y{components - 1}": 9, f"y{components - 3}": 10}
    used = sorted({x for inputs, _ in table for x in inputs if x.startswith("e")})
    spec["test_cases"] = {"tc": {"assumption": " and ".join(f"0 <= {e} <= 10" for e in used),
                                 "guarantee": " and ".join(f"{y} <= {g}"
                                                           for y, g in goal.items())}}
    return Library.from_dict(spec, source=f"dag(seed={seed})"), table, goal


def enumerate_dag(table, goal, env_hi: int = 10, chunk: int = 1 << 21):
    """Cheapest valid setup by checking every setup (numpy, in chunks of linear indices):
    valid iff every input's upper bound (10 for e_j, the driver's ``out`` for y_k) is within
    the model's ``hi`` and every goal variable's bound within the goal."""
    sizes = [len(row) for _, row in table]
    total = int(np.prod(sizes, dtype=np.int64))
    strides = np.cumprod([1] + sizes[:0:-1])[::-1]
    his = [{x: np.array([h[x] for h, _, _ in row]) for x in inputs} for inputs, row in table]
    outs = [np.array([o for _, o, _ in row]) for _, row in table]
    costs = [np.array([c for _, _, c in row]) for _, row in table]
    best_cost, best_index = np.inf, -1
    for start in range(0, total, chunk):
        index = np.arange(start, min(start + chunk, total), dtype=np.int64)
        digits = [(index // strides[k]) % sizes[k] for k in range(len(sizes))]
        valid = np.ones(len(index), dtype=bool)
        cost = np.zeros(len(index))
        for k, (inputs, _) in enumerate(table):
            cost += costs[k][digits[k]]
            for x in inputs:
                bound = env_hi if x.startswith("e") else outs[int(x[1:])][digits[int(x[1:])]]
                valid &= bound <= his[k][x][digits[k]]
        for y, g in goal.items():
            k = int(y[1:])
            valid &= outs[k][digits[k]] <= g
        if valid.any():
            i = int(np.argmin(np.where(valid, cost, np.inf)))
            if cost[i] < best_cost:
                best_cost, best_index = float(cost[i]), int(index[i])
    return (None if best_index < 0 else best_cost), total


def bench_dag(seeds) -> list[dict]:
    rows = []
    for seed in seeds:
        lib, table, goal = dag_library(seed)
        seconds, result = best_of(lambda lib=lib: configure(lib, "tc"), 3)
        enum_seconds, (best, total) = best_of(
            lambda table=table, goal=goal: enumerate_dag(table, goal), 1)
        optimal = (best is None and result.cost is None) or (
            best is not None and result.cost is not None and abs(result.cost - best) < 1e-6)
        rows.append({"case": f"(c) 12 components × 4–6 models, seed {seed}", "setups": total,
                     "seconds": seconds, "status": result.status.value, "cost": result.cost,
                     "optimum_by_enumeration": best, "optimal": optimal,
                     "enumeration_seconds": enum_seconds,
                     "speedup_vs_enumeration": enum_seconds / seconds,
                     "method": result.method, "target": "optimal and ≥ 10× faster"})
    return rows


def bench_monitor(samples: int) -> list[dict]:
    """Smooth recorded signals that leave the domain now and then (a few hundred violations)."""
    rng = np.random.default_rng(0)
    runs = 100
    steps = samples // runs
    t = np.arange(steps) * 0.01
    phase = rng.uniform(0, 2 * np.pi, (runs, 1))
    v = (20 + 19.5 * np.sin(t / 7 + phase)).ravel()
    a_lat = (2.5 * np.sin(t / 3 + 2 * phase) + rng.normal(0, 0.2, (runs, steps))).ravel()
    traces = TraceSet(("ego.v", "ego.a_lat"), np.tile(t, runs),
                      np.column_stack([v, a_lat]), np.arange(runs + 1) * steps,
                      tuple(f"r{i}" for i in range(runs)))
    contract = Contract.from_strings("0 <= ego.v <= 40 and abs(ego.a_lat) <= 4", "true")
    seconds, report = best_of(lambda: monitor(traces, {"KS": contract}), 3)
    reference, _ = best_of(lambda: [np.flatnonzero(~(v >= 0)), np.flatnonzero(~(v <= 40)),
                                    np.flatnonzero(~(np.abs(a_lat) <= 4))], 3)
    return [{"case": f"(b) monitor, 3 invariant clauses, {runs * steps:,} samples",
             "seconds": seconds, "samples_per_s": runs * steps / seconds,
             "violations": len(report.violations),
             "numpy_reference_seconds": reference,
             "ratio_to_numpy_reference": seconds / reference, "target": "≥ 1e7 samples/s"}]


def bench_temporal(samples: int) -> list[dict]:
    """A temporal clause over recorded runs (100 runs, 100 Hz) against rtamt's discrete-time
    offline monitor on one run of the same signal, in samples per second."""
    rng = np.random.default_rng(1)
    runs, steps = 100, samples // 100
    t = np.arange(steps) * 0.01
    a = (3 * np.sin(t[None, :] / 2 + rng.uniform(0, 6, (runs, 1)))
         + rng.normal(0, 0.3, (runs, steps))).ravel()
    traces = TraceSet(("ego.a_long",), np.tile(t, runs), a[:, None],
                      np.arange(runs + 1) * steps, tuple(f"r{i}" for i in range(runs)))
    text = "ego.a_long < -2 implies eventually[0, 0.5] ego.a_long >= -1"
    contract = Contract.from_strings("true", text)
    seconds, report = best_of(lambda: monitor(traces, {"M": contract}), 3)
    row = {"case": f"(d) temporal monitor '{text}', {runs * steps:,} samples",
           "seconds": seconds, "samples_per_s": runs * steps / seconds,
           "violations": len(report.violations)}
    try:
        import rtamt
    except ImportError:
        return [row | {"rtamt": "not installed"}]
    n = min(steps, 20_000)
    spec = rtamt.StlDiscreteTimeSpecification()
    spec.declare_var("a", "float")
    spec.spec = "(a < -2) implies (eventually[0,50] (a >= -1))"  # 0.5 s at 100 Hz
    spec.set_sampling_period(10, "ms", 0.1)
    spec.parse()
    data = {"time": (np.arange(n) * 10).tolist(), "a": a[:n].tolist()}
    rt_seconds, _ = best_of(lambda: spec.evaluate(data), 1)
    return [row | {"rtamt_samples_per_s": n / rt_seconds,
                   "speedup_vs_rtamt": (runs * steps / seconds) / (n / rt_seconds)}]


def bench_until(samples: int) -> list[dict]:
    """(e): module docs."""
    from simcred.contracts.temporal import Timeline, _until_offsets, uniform_step, until

    rng = np.random.default_rng(2)
    uniform = np.arange(samples) * 0.01
    jittered = np.cumsum(rng.uniform(0.005, 0.015, samples))  # 100 Hz on average
    phi, psi = rng.normal(size=samples), rng.normal(size=samples)
    rows = []
    for sampling, t in (("at 100 Hz", uniform), ("non-uniform (steps 5-15 ms)", jittered)):
        timeline = Timeline.single(t)
        for past, name in ((False, "until"), (True, "since")):
            seconds, _ = best_of(lambda past=past, timeline=timeline: until(
                phi, psi, timeline, 0, 10, past=past, boolean=False), 3)
            m = min(samples, 10**5)
            part = Timeline.single(t[:m])
            start, stop = part.window(0, 10, past=past)
            loop, _ = best_of(lambda past=past, start=start, stop=stop, m=m: _until_offsets(
                phi[:m], psi[:m], start, stop, past=past), 1)
            rows.append({"case": f"(e) {name}[0, 10] {sampling}, {samples:,} samples",
                         "uniform": uniform_step(t) is not None,
                         "seconds": seconds, "samples_per_s": samples / seconds,
                         "loop_samples": m, "loop_seconds": loop,
                         "loop_samples_per_s": m / loop,
                         "speedup_vs_loop": (samples / seconds) / (m / loop),
                         "target": "10⁶ samples < 2 s"})
    return rows


CEGIS_LIMIT_S = 30


def bench_library(seeds) -> list[dict]:
    """(f): module docs."""
    import signal

    from contract_libraries import fan_in, non_convex

    def stop(signum, frame):
        raise TimeoutError

    rows = []
    for make, size in ((non_convex, (20, 6)), (non_convex, (30, 8)), (fan_in, (10, 4)),
                       (fan_in, (20, 6))):
        for seed in seeds:
            library, oracle = make(*size, seed)
            seconds, found = best_of(lambda library=library: configure(library, "tc"), 1)
            previous = signal.signal(signal.SIGALRM, stop)
            signal.alarm(CEGIS_LIMIT_S)
            try:
                cegis_seconds, cegis = best_of(
                    lambda library=library: configure(library, "tc", search="cegis"), 1)
                cegis_cost = cegis.cost
            except TimeoutError:
                cegis_seconds, cegis_cost = None, "no answer"
            finally:
                signal.alarm(0)
                signal.signal(signal.SIGALRM, previous)
            rows.append({"case": f"(f) {make.__name__} {size[0]} × {size[1]}, seed {seed}",
                         "seconds": seconds, "status": found.status.value, "cost": found.cost,
                         "oracle_cost": oracle, "optimal": found.cost == oracle,
                         "method": found.method.split(";")[0],
                         "cegis_seconds": cegis_seconds, "cegis_cost": cegis_cost,
                         "cegis_limit_s": CEGIS_LIMIT_S,
                         "speedup_vs_cegis": (cegis_seconds or CEGIS_LIMIT_S) / seconds})
    return rows


def bench_quotient(sizes, others: bool) -> list[dict]:
    """(g): module docs."""
    import os
    import subprocess
    import tempfile

    import yaml
    from contract_libraries import chain_spec, fan_in, non_convex

    from simcred.contracts.algebra import equivalent
    from simcred.contracts.configure import missing_model_requirement
    from simcred.contracts.expr import children
    from simcred.contracts.requirement import requirement

    def size(e) -> int:
        return 1 + sum(size(c) for c in children(e))

    cases = []  # (label, library, its dictionary for the CLI or None, missing component)
    for n in sizes:
        spec, _ = chain_spec(n, 3, 1)
        cases.append((f"chain of {n}", Library.from_dict(spec, source=f"chain({n}, 3, 1)"),
                      spec, f"I{n // 2}"))
    if others:
        cases += [("non-convex 20 × 6", non_convex(20, 6, 0)[0], None, "I10"),
                  ("fan-in 20 × 6, a sensor missing", fan_in(20, 6, 0)[0], None, "S7"),
                  ("fan-in 20 × 6, AD missing", fan_in(20, 6, 0)[0], None, "AD"),
                  ("DAG 12 × 4–6 (section c, seed 0)", dag_library(0)[0], None, "C6")]
    rows = []
    for label, library, spec, missing in cases:
        setup = configure(library, "tc", explain=0).setup
        given = {c: m for c, m in setup.items() if c != missing}
        quotient = missing_model_requirement(library, "tc", given)
        seconds, new = best_of(lambda library=library, given=given: requirement(
            library, "tc", given), 1)
        old_seconds, old = best_of(lambda library=library, given=given: requirement(
            library, "tc", given, projection_method="qe"), 1)
        cli_seconds = cli_exit = None
        if spec is not None:
            with tempfile.TemporaryDirectory() as folder:
                path = Path(folder) / "chain.yaml"
                path.write_text(yaml.safe_dump(spec))
                command = [sys.executable, "-m", "simcred.cli", "contracts", "quotient",
                           str(path), "--test-case", "tc",
                           *(f"--given={c}={m}" for c, m in given.items())]
                env = {**os.environ, "PYTHONPATH": os.pathsep.join(
                    filter(None, [str(ROOT / "src"), os.environ.get("PYTHONPATH")]))}
                cli_seconds, done = best_of(lambda command=command, env=env: subprocess.run(
                    command, capture_output=True, text=True, check=False, env=env), 1)
                cli_exit = done.returncode
        rows.append({"case": f"(g) quotient, {label}, {len(given)} given models",
                     "given_models": len(given), "seconds": seconds,
                     "quotient_nodes": size(quotient.assumption) + size(quotient.guarantee),
                     "projected": new.projected, "method": new.method,
                     "assumption": new.assumption, "guarantee": new.guarantee,
                     "old_seconds": old_seconds, "old_projected": old.projected,
                     "old_assumption_chars": len(old.assumption),
                     "old_guarantee_chars": len(old.guarantee),
                     "same_text": (old.assumption, old.guarantee) == (new.assumption,
                                                                       new.guarantee),
                     # z3: is the classic path's projection the same contract as the new one?
                     "old_equivalent": (equivalent(old.contract, new.contract,
                                                   types=library.types).status.value
                                        if old.projected and new.projected else None),
                     "speedup_vs_old": old_seconds / seconds,
                     "cli_seconds": cli_seconds, "cli_exit": cli_exit,
                     "target": "19 given models < 10 s"})
    return rows


SECTIONS = ("configuration", "scale", "monitor", "temporal", "until", "library", "quotient")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--only", nargs="+", choices=SECTIONS, default=list(SECTIONS))
    args = parser.parse_args()
    quick = args.quick
    benches = {"configuration": lambda: bench_configuration(range(2) if quick else range(5)),
               "scale": lambda: bench_dag(range(2) if quick else range(5)),
               "monitor": lambda: bench_monitor(10**6 if quick else 10**7),
               "temporal": lambda: bench_temporal(10**5 if quick else 10**6),
               "until": lambda: bench_until(10**5 if quick else 10**6),
               "library": lambda: bench_library(range(1) if quick else range(2)),
               "quotient": lambda: bench_quotient((6, 20) if quick else (6, 11, 16, 20, 30),
                                                  others=not quick)}
    results = {"machine": machine()}
    results.update({name: benches[name]() if name in args.only else [] for name in SECTIONS})
    table = Table(title="simcred contracts benchmarks")
    for column in ("case", "seconds", "result", "note"):
        table.add_column(column)
    for r in results["configuration"]:
        table.add_row(r["case"], f"{r['seconds']:.2f}",
                      f"{r['status']}, cost {r['cost']}, optimal: {r['optimal']}",
                      f"{r['speedup_vs_cegis']:.0f}× faster than CEGIS "
                      f"({r['cegis_seconds']:.2f} s); target < 5 s")
    for r in results["scale"]:
        table.add_row(r["case"], f"{r['seconds']:.3f}",
                      f"{r['status']}, cost {r['cost']}, optimal: {r['optimal']}",
                      f"{r['speedup_vs_enumeration']:.0f}× faster than enumerating "
                      f"{r['setups']:,} setups ({r['enumeration_seconds']:.2f} s); target ≥ 10×")
    for r in results["monitor"]:
        table.add_row(r["case"], f"{r['seconds']:.3f}", f"{r['samples_per_s']:.3g} samples/s",
                      f"{r['ratio_to_numpy_reference']:.1f}× the bare numpy expression; "
                      f"{r['target']}")
    for r in results["temporal"]:
        note = (f"{r['speedup_vs_rtamt']:.0f}× rtamt's samples/s "
                f"({r['rtamt_samples_per_s']:.3g})" if "speedup_vs_rtamt" in r else r["rtamt"])
        table.add_row(r["case"], f"{r['seconds']:.3f}", f"{r['samples_per_s']:.3g} samples/s",
                      note)
    for r in results["library"]:
        cegis = (f"CEGIS {r['cegis_seconds']:.1f} s, cost {r['cegis_cost']}"
                 if r["cegis_seconds"] is not None
                 else f"CEGIS no answer in {r['cegis_limit_s']} s")
        table.add_row(r["case"], f"{r['seconds']:.2f}",
                      f"{r['status']}, cost {r['cost']}, optimal (generator's DP): "
                      f"{r['optimal']}",
                      f"{'≥ ' if r['cegis_seconds'] is None else ''}"
                      f"{r['speedup_vs_cegis']:.0f}× faster ({cegis}); target < 10 s")
    for r in results["until"]:
        table.add_row(r["case"], f"{r['seconds']:.3f}", f"{r['samples_per_s']:.3g} samples/s",
                      f"{r['speedup_vs_loop']:.0f}× the loop over window offsets "
                      f"({r['loop_samples_per_s']:.3g} samples/s on {r['loop_samples']:,}); "
                      f"{r['target']}")
    for r in results["quotient"]:
        old = ("same text" if r["same_text"] else
               f"projected: {r['old_projected']}, {r['old_assumption_chars']} + "
               f"{r['old_guarantee_chars']} characters" + (
                   f", equivalent: {r['old_equivalent']}" if r["old_projected"] else ""))
        table.add_row(r["case"], f"{r['seconds']:.2f}",
                      f"assume {r['assumption']}; guarantee {r['guarantee']} "
                      f"({r['quotient_nodes']} quotient nodes)",
                      f"{r['speedup_vs_old']:.0f}× the classic qe path "
                      f"({r['old_seconds']:.1f} s, {old}); "
                      + (f"CLI {r['cli_seconds']:.1f} s; " if r["cli_seconds"] else "")
                      + r["target"])
    Console(width=160).print(table)
    name = "contracts" + ("-quick" if quick else "") + (
        "" if set(args.only) == set(SECTIONS) else "-" + "-".join(args.only))
    out = ROOT / "benchmarks" / "results" / f"{name}.json"
    out.write_text(json.dumps(results, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
