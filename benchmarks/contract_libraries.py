"""Generated contract libraries for configuration at library scale (issue 28, item 2), with an
independent exact optimum for each (dynamic programming on the generator's own numbers, no
contract reasoning), so that benchmarks and tests can check optimality beyond brute force.

* :func:`fan_in` — ``components`` sensor components S_k read the environment speed ``v`` and
  drive an error ``e_k``; model j of S_k assumes a speed range and guarantees
  ``0 <= e_k <= err_kj`` (accurate models cost more); one AD component reads every ``e_k`` and
  its only model assumes ``e_0 + … + e_{n-1} <= budget`` (a sum: outside the interval fragment),
  the budget between the sum of the best and of the median errors, so that only expensive models
  meet it. Test case: ``10 <= v <= 30``, guarantee ``true``. Oracle: a knapsack over the
  integer errors.
* :func:`non_convex` — a chain I_0 … I_{n-1} (x_k → x_{k+1}); model j of I_k assumes a *union* of
  two intervals of x_k with a gap (a non-convex validity domain; wider domains cost more) and
  guarantees an interval of x_{k+1}. Test case: ``1 <= x0 <= 5``, guarantee ``x_n <= 12``.
  Oracle: dynamic programming along the chain over the chosen model's output interval.

* :func:`chain` — interval contracts along a chain I_0 … I_{n-1} (x_k → x_{k+1}); model j of
  I_k assumes ``0 <= x_k <= hi`` and guarantees ``0 <= x_{k+1} <= out`` (wider domains and
  tighter outputs cost more). Test case: ``0 <= x0 <= 10``, guarantee ``x_n <= 9``. Returns
  ``(Library, table)`` with the table of ``(model, hi, out, cost)`` per component (the
  benchmarks' closed-form enumeration and the quotient tests' closed form use it).

Seeded with numpy ``default_rng(seed)``; :func:`fan_in` and :func:`non_convex` return
``(Library, optimum cost or None)``.
"""

from __future__ import annotations

import numpy as np

from simcred.contracts.library import Library


def fan_in(components: int, models: int, seed: int) -> tuple[Library, float | None]:
    rng = np.random.default_rng(seed)
    spec = {"variables": {"v": {"unit": "m/s"}}, "components": {}, "models": {},
            "architecture": [],
            "test_cases": {"tc": {"assumption": "10 <= v <= 30", "guarantee": "true"}}}
    rows = []  # per sensor: [(error, cost, valid for 10..30)]
    for k in range(components):
        spec["variables"][f"e{k}"] = {"unit": "m"}
        spec["components"][f"S{k}"] = {"inputs": ["v"], "outputs": [f"e{k}"]}
        spec["architecture"].append(f"S{k}")
        errors = np.sort(rng.integers(1, 50, size=models))  # model 0: the most accurate
        row = []
        for j, err in enumerate(errors):
            cost = int(rng.integers(1, 5)) + 3 * (models - j)
            top = int(rng.integers(25, 60))
            spec["models"][f"S{k}_{j}"] = {
                "implements": f"S{k}", "cost": cost,
                "contract": {"assumption": f"0 <= v <= {top}",
                             "guarantee": f"0 <= e{k} <= {int(err)}"}}
            row.append((int(err), cost, top >= 30))
        rows.append(row)
    inputs = [f"e{k}" for k in range(components)]
    spec["variables"]["cmd"] = {"unit": "m"}
    spec["components"]["AD"] = {"inputs": inputs, "outputs": ["cmd"]}
    spec["architecture"].append("AD")
    budget = sum(sorted(e for e, _, _ in row)[0] + sorted(e for e, _, _ in row)[models // 2]
                 for row in rows) // 2
    spec["models"]["AD_0"] = {"implements": "AD", "cost": 1, "contract": {
        "assumption": " + ".join(inputs) + f" <= {budget}", "guarantee": "cmd <= 1"}}
    library = Library.from_dict(spec, source=f"fan_in({components}, {models}, {seed})")
    # knapsack: least cost with total error <= budget, valid models only
    best = {0: 0}
    for row in rows:
        step = {}
        for total, cost in best.items():
            for err, c, ok in row:
                if ok and total + err <= budget and step.get(total + err, 1e18) > cost + c:
                    step[total + err] = cost + c
        best = step
    return library, (float(min(best.values()) + 1) if best else None)


def non_convex(components: int, models: int, seed: int) -> tuple[Library, float | None]:
    rng = np.random.default_rng(seed)
    spec = {"variables": {f"x{k}": {"unit": "m"} for k in range(components + 1)},
            "components": {f"I{k}": {"inputs": [f"x{k}"], "outputs": [f"x{k + 1}"]}
                           for k in range(components)},
            "models": {}, "architecture": [f"I{k}" for k in range(components)],
            "test_cases": {"tc": {"assumption": "1 <= x0 <= 5",
                                  "guarantee": f"x{components} <= 12"}}}
    rows = []
    for k in range(components):
        row = []
        for j in range(models):
            a = int(rng.integers(0, 2))
            b = a + int(rng.integers(4, 10))
            c = b + int(rng.integers(1, 4))  # a gap: the domain is two intervals
            d = c + int(rng.integers(2, 10))
            lo = int(rng.integers(0, 4))
            hi = lo + int(rng.integers(1, 6))
            cost = int(rng.integers(1, 20)) + 2 * (d - a)
            spec["models"][f"M{k}_{j}"] = {
                "implements": f"I{k}", "cost": cost,
                "contract": {"assumption": f"{a} <= x{k} <= {b} or {c} <= x{k} <= {d}",
                             "guarantee": f"{lo} <= x{k + 1} <= {hi}"}}
            row.append(((a, b), (c, d), (lo, hi), cost))
        rows.append(row)
    library = Library.from_dict(spec, source=f"non_convex({components}, {models}, {seed})")

    def inside(box, first, second):
        return any(lo <= box[0] and box[1] <= hi for lo, hi in (first, second))

    best = {(1, 5): 0}  # input interval of the next component → least cost so far
    for row in rows:
        step = {}
        for box, cost in best.items():
            for first, second, out, c in row:
                if inside(box, first, second) and step.get(out, 1e18) > cost + c:
                    step[out] = cost + c
        best = step
    valid = [cost for out, cost in best.items() if out[1] <= 12]
    return library, (float(min(valid)) if valid else None)


def chain(components: int, candidates: int, seed: int) -> tuple[Library, list]:
    """I_k maps x_k to x_{k+1}; model (k, j) assumes 0 <= x_k <= hi and guarantees
    0 <= x_{k+1} <= out; wider domains and tighter outputs cost more."""
    spec, table = chain_spec(components, candidates, seed)
    return Library.from_dict(spec, source=f"chain(seed={seed})"), table


def chain_spec(components: int, candidates: int, seed: int) -> tuple[dict, list]:
    """:func:`chain` as the library's dictionary (for a YAML file) and its table."""
    rng = np.random.default_rng(seed)
    spec = {"variables": {f"x{k}": {"unit": "m"} for k in range(components + 1)},
            "components": {f"I{k}": {"inputs": [f"x{k}"], "outputs": [f"x{k + 1}"]}
                           for k in range(components)},
            "models": {}, "architecture": [f"I{k}" for k in range(components)],
            "test_cases": {"tc": {"assumption": "0 <= x0 <= 10",
                                  "guarantee": f"x{components} <= 9"}}}
    table = []
    for k in range(components):
        row = []
        for j in range(candidates):
            hi, out = int(rng.integers(6, 16)), int(rng.integers(5, 14))
            cost = round(float(hi - out) * 0.5 + 10 + rng.uniform(0, 3), 2)
            spec["models"][f"M{k}_{j}"] = {
                "implements": f"I{k}", "cost": cost,
                "contract": {"assumption": f"0 <= x{k} <= {hi}",
                             "guarantee": f"0 <= x{k + 1} <= {out}"}}
            row.append((f"M{k}_{j}", hi, out, cost))
        table.append(row)
    return spec, table
