"""The plan's simulated data sets: units and pairs drawn with replacement, renamed as new units;
a drawn pair keeps its two members together, and swapping members at random puts one law on
both sides."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from simcred.compare.design import unit_keys
from simcred.regions.cells import SOURCE_RUN
from simcred.traces import RUN_INFO, TraceSet
from simcred.validate.draws import draw_pairs, draw_units


def _set(tag: str, keys: list[str], level: float) -> TraceSet:
    """One run per key (two for keys ending in '2': segments of one unit), value = level + the
    key's index, so every row says which side and unit it came from."""
    runs, info = [], {}
    for i, key in enumerate(keys):
        for seg in range(2 if key.endswith("2") else 1):
            run = f"{tag}{key}@{seg}"
            runs.append((run, level + i))
            info[run] = {SOURCE_RUN: key, "driver": key}
    lengths = [3] * len(runs)
    values = np.concatenate([np.full((n, 1), v) for (_, v), n in zip(runs, lengths, strict=True)])
    return TraceSet(("x",), np.tile(np.arange(3.0), len(runs)), values,
                    np.r_[0, np.cumsum(lengths)], tuple(r for r, _ in runs),
                    {RUN_INFO: info}, tag)


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 40), seed=st.integers(0, 2**32 - 1), k=st.integers(1, 6))
def test_drawn_pairs_keep_members_together_and_are_new_units(n, seed, k):
    keys = [f"k{i}" for i in range(k)]  # k2 has two segments
    ref, cand = _set("r", keys, 0.0), _set("c", keys, 100.0)
    a, b = draw_pairs(ref, cand, SOURCE_RUN, n, np.random.default_rng(seed))
    ka, kb = unit_keys(a, SOURCE_RUN, "pairs"), unit_keys(b, SOURCE_RUN, "pairs")
    assert sorted(set(ka)) == sorted(set(kb)) and len(set(ka)) == n  # n pairs, matched keys
    first_a = {k: a.values[a.offsets[i], 0] for i, k in enumerate(ka)}
    first_b = {k: b.values[b.offsets[i], 0] for i, k in enumerate(kb)}
    for key in first_a:  # one member from each side, of the same original unit
        one, two = sorted((first_a[key], first_b[key]))
        assert one < 100 <= two and two - 100 == one


def test_swapping_members_puts_both_sides_on_one_law():
    keys = [f"k{i}" for i in range(5)]
    ref, cand = _set("r", keys, 0.0), _set("c", keys, 100.0)
    a, _ = draw_pairs(ref, cand, SOURCE_RUN, 4000, np.random.default_rng(1))
    from_candidate = np.mean(a.values[a.offsets[:-1], 0] >= 100)
    assert abs(from_candidate - 0.5) < 0.03  # each side half reference, half candidate


def test_drawn_units_carry_all_their_runs_and_facts():
    traces = _set("r", ["a", "b2", "c"], 0.0)
    drawn = draw_units(traces, "driver", 50, np.random.default_rng(3), "x")
    keys = unit_keys(drawn, "driver", "groups")
    assert len(set(keys)) == 50
    for unit in set(keys):  # a unit drawn from 'b2' brings both of its segments
        rows = [i for i, k in enumerate(keys) if k == unit]
        level = drawn.values[drawn.offsets[rows[0]], 0]
        assert len(rows) == (2 if level == 1.0 else 1)
    assert set(drawn.metadata[RUN_INFO]) == set(drawn.run_ids)
