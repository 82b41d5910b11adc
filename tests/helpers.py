import numpy as np

from simcred.traces import TraceSet


def random_walk_set(rng, runs, drift, min_len=2, max_len=30, source="<test>"):
    """Runs of a 2-D random walk with per-run lengths in [min_len, max_len]."""
    lengths = rng.integers(min_len, max_len + 1, size=runs)
    out = []
    for length in lengths:
        steps = rng.normal(drift, 1.0, size=(length, 2))
        xy = np.cumsum(steps, axis=0) + rng.normal(0, 2, size=2)
        out.append({"t": np.arange(length) * 0.1, "x": xy[:, 0], "y": xy[:, 1]})
    return TraceSet.from_runs(out, source=source)


def runs_of(traces, features):
    """The literal oracle's input: one (T, F) array per run."""
    values = traces.features(features)
    return [values[lo:hi] for lo, hi in zip(traces.offsets[:-1], traces.offsets[1:], strict=True)]




def ar_set(rng, runs, phi, length=30, source="<test>"):
    """Runs of a 2-D AR(1) process x' = phi x + noise, started in its stationary law.

    phi and -phi have the same stationary (and start) distribution but opposite transitions.
    """
    scale = 1.0 / np.sqrt(1 - phi * phi)
    xy = np.empty((runs, length, 2))
    xy[:, 0] = rng.normal(0, scale, size=(runs, 2))
    for t in range(1, length):
        xy[:, t] = phi * xy[:, t - 1] + rng.normal(0, 1, size=(runs, 2))
    return TraceSet.from_runs(
        [{"t": np.arange(length) * 0.1, "x": r[:, 0], "y": r[:, 1]} for r in xy], source=source
    )


def tied_set(rng, runs, shift, source):
    """A feature with a 60 % atom at 0 (a quantile edge at the minimum is dropped) and one with
    three values (midpoint edges)."""
    out = []
    for _ in range(runs):
        n = int(rng.integers(2, 25))
        x = np.where(rng.random(n) < 0.6, 0.0, np.round(rng.exponential(1, n) + shift, 1))
        out.append({"t": np.arange(n) * 0.1, "x": x, "y": rng.integers(0, 3, n) * 1.0})
    return TraceSet.from_runs(out, source=source)


def leaf_commands(group, prefix=()):
    """(path, command) of every leaf command of a click/typer group (duck-typed: typer vendors
    click)."""
    found = []
    for name, command in sorted(group.commands.items()):
        if hasattr(command, "commands"):
            found += leaf_commands(command, (*prefix, name))
        else:
            found.append(((*prefix, name), command))
    return found


def cli_compare_known_answer(capsys, a, b, feature, same, *options):
    """``simcred compare A B --json`` on one feature (4 bins, 99 permutations, seed 2): a set
    against its own copy is the same (distance 0, chain kept), against a changed one different.
    Returns the JSON document for further checks."""
    import json

    from simcred.cli import run

    assert run(["compare", str(a), str(b), "-f", feature, "--bins", "4", "--permutations", "99",
                "--seed", "2", *options, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["chain"]["rejected"] is (not same)
    assert (doc["distance"] == 0.0) is same
    return doc


def benchmark_module(name: str):
    """A module of benchmarks/ loaded by its path: putting benchmarks/ on sys.path would shadow
    installed packages for every later test (benchmarks/sumo.py hides SUMO's ``sumo``)."""
    import importlib.util
    import sys
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"_bench_{name}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the file runs
    spec.loader.exec_module(module)
    return module
