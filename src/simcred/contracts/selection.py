"""The proposal step of counterexample-guided configuration: the cheapest selection of one model
per component that passes every constraint learned at counterexample points (the general case,
outside the interval fragment; replaces z3 ``Optimize``, which took ~89 % of the time).

At a point p every model's assumption a and saturated guarantee g are constants, and a selection
s passes p iff  G_s → (g_tc ∧ (¬a_tc ∨ A_s))  with G_s = ∧_c g[c, s_c], A_s = ∧_c a[c, s_c]
(the two refinement implications at p, as in :func:`simcred.contracts.configure._valid_at`).
So a point is passed when some chosen model's guarantee fails there, or — if the test case's
guarantee holds there — when every chosen model's assumption holds (or the test case's assumption
does not).

Exact depth-first branch-and-bound over the components, cheapest model first, with all points
handled at once as boolean numpy vectors; a partial selection is cut when the cost bound (cost so
far + the cheapest model of every remaining component) reaches the best found, or when some point
can no longer be passed (all its chosen guarantees hold, it needs one to fail, and no remaining
component has a model whose guarantee fails there); a state (level, which points still have all
guarantees and all assumptions holding, which forbidden combinations it still matches) reached
before at no higher cost is not expanded again. Costs are exact rationals.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np


@dataclass
class Constraints:
    """Learned points: per component a (models × points) table of assumption and guarantee
    values, and per point the test case's assumption and saturated guarantee."""

    components: list[str]
    models: dict[str, list[str]]
    assumption: dict[str, list[list[bool]]] = field(default_factory=dict)
    guarantee: dict[str, list[list[bool]]] = field(default_factory=dict)
    target_assumption: list[bool] = field(default_factory=list)
    target_guarantee: list[bool] = field(default_factory=list)

    def add(self, a: dict[str, list[bool]], g: dict[str, list[bool]], a_tc: bool, g_tc: bool
            ) -> None:
        """One point: ``a[c][j]``/``g[c][j]`` for model j of component c."""
        for c in self.components:
            self.assumption.setdefault(c, []).append(list(a[c]))
            self.guarantee.setdefault(c, []).append(list(g[c]))
        self.target_assumption.append(a_tc)
        self.target_guarantee.append(g_tc)


def cheapest(constraints: Constraints, costs: dict[str, Fraction],
             forbidden: Sequence[Mapping[str, str]] = ()) -> dict[str, str] | None:
    """The cheapest selection passing every point (ties: candidate order) and containing no
    ``forbidden`` combination (component → model: models whose guarantees contradict), or
    None."""
    comps = constraints.components
    n = len(constraints.target_assumption)
    models = [constraints.models[c] for c in comps]
    a = [np.array(constraints.assumption[c], dtype=bool).T.reshape(len(models[k]), n)
         if n else np.ones((len(models[k]), 0), bool) for k, c in enumerate(comps)]
    g = [np.array(constraints.guarantee[c], dtype=bool).T.reshape(len(models[k]), n)
         if n else np.ones((len(models[k]), 0), bool) for k, c in enumerate(comps)]
    a_tc = np.array(constraints.target_assumption, dtype=bool)
    g_tc = np.array(constraints.target_guarantee, dtype=bool)
    # can_break[k][p]: some component from k on has a model whose guarantee fails at p
    can_break = np.zeros((len(comps) + 1, n), dtype=bool)
    for k in range(len(comps) - 1, -1, -1):
        can_break[k] = can_break[k + 1] | ~g[k].all(axis=0)
    cost = [[costs[m] for m in row] for row in models]
    min_rest = [Fraction(0)] * (len(comps) + 1)
    for k in range(len(comps) - 1, -1, -1):
        min_rest[k] = min_rest[k + 1] + min(cost[k])
    needs_break = ~g_tc  # points where the test case's guarantee fails: G_s must fail
    best: dict = {"cost": None, "choice": None}
    seen: dict = {}

    def feasible(k, all_g, all_a) -> bool:
        # a point with every chosen guarantee holding is lost when it needs a failing guarantee
        # (g_tc false, or a_tc true with some assumption false) and none can fail any more
        stuck = all_g & (needs_break | (a_tc & ~all_a)) & ~can_break[k]
        return not stuck.any()

    def alive(chosen) -> tuple[bool, ...]:
        # which forbidden combinations the selection so far still contains all it decided of
        return tuple(all(f[c] == m for c, m in zip(comps, chosen, strict=False) if c in f)
                     for f in forbidden)

    def expand(k, total, all_g, all_a, chosen) -> None:
        if best["cost"] is not None and total + min_rest[k] >= best["cost"]:
            return
        if not feasible(k, all_g, all_a):
            return
        matching = alive(chosen)
        if k == len(comps):
            if not any(matching):
                best["cost"], best["choice"] = total, list(chosen)
            return
        key = (k, all_g.tobytes(), all_a.tobytes(), matching)
        if key in seen and seen[key] <= total:
            return
        seen[key] = total
        for j in sorted(range(len(models[k])), key=lambda j: (cost[k][j], models[k][j])):
            chosen.append(models[k][j])
            expand(k + 1, total + cost[k][j], all_g & g[k][j], all_a & a[k][j], chosen)
            chosen.pop()

    expand(0, Fraction(0), np.ones(n, dtype=bool), np.ones(n, dtype=bool), [])
    return None if best["choice"] is None else dict(zip(comps, best["choice"], strict=True))
