"""The known-truth designs of tests/response_designs.py are what they claim to be."""

from __future__ import annotations

import numpy as np
import pytest

import response_designs as rd
from simcred.traces import RUN_INFO


def info(ts, key):
    return [ts.metadata[RUN_INFO][r][key] for r in ts.run_ids]


@pytest.mark.parametrize("name", sorted(rd.H0))
def test_h0_designs_are_seeded_and_well_formed(name):
    d1 = rd.H0[name](np.random.default_rng(5))
    d2 = rd.H0[name](np.random.default_rng(5))
    d3 = rd.H0[name](np.random.default_rng(6))
    assert d1.a.equals(d2.a) and d1.b.equals(d2.b)
    assert not np.array_equal(d1.a.values, d3.a.values)
    for ts in (d1.a, d1.b):
        assert set(d1.features) <= set(ts.signals)
        assert set(d1.inputs) <= set(d1.features)
        if d1.group_by:
            assert all(isinstance(g, str) for g in info(ts, d1.group_by))
    if d1.pair_by == "run_id":
        assert d1.a.run_ids == d1.b.run_ids


def test_driving_signals_follow_the_openacc_conventions():
    d = rd.defect(np.random.default_rng(0), "none", paired=False)
    for ts in (d.a, d.b):
        v, vl, gap = ts.column("v"), ts.column("v_leader"), ts.column("gap")
        np.testing.assert_allclose(ts.column("dv"), vl - v)
        assert v.min() >= 0 and gap.min() > 0
        steps = ts.lengths[0]
        assert np.all(ts.lengths == rd.EPISODE) and np.allclose(np.diff(ts.time[:steps]), rd.DT)
        # ballistic update with the leader speed held over the step
        runs = ts.n_runs
        g, vv, a, lead = (ts.column(s).reshape(runs, steps) for s in ("gap", "v", "a",
                                                                        "v_leader"))
        np.testing.assert_allclose(vv[:, 1:], vv[:, :-1] + a[:, :-1] * rd.DT, atol=1e-9)
        np.testing.assert_allclose(g[:, 1:], g[:, :-1] + (lead[:, :-1] - (vv[:, 1:] + vv[:, :-1])
                                                         / 2) * rd.DT, atol=1e-9)


def test_leaders_split_is_deterministic_and_uses_two_halves():
    d = rd.leaders_split(np.random.default_rng(1))
    files_a, files_b = set(info(d.a, "file")), set(info(d.b, "file"))
    assert {frozenset(files_a), frozenset(files_b)} == {frozenset(h) for h in rd.HALVES}
    assert d.inputs == ("v_leader",) and "v_leader" in d.features
    # a deterministic response: the same state gives the same next (gap, v) in A and B
    state = (5.0 + 10 * np.random.default_rng(0).random((3, 1)))
    out = [rd.simulate(np.random.default_rng(s), np.hstack([state, state + 1]), state[:, 0] * 2,
                       state[:, 0], rd.DETERMINISTIC) for s in (1, 2)]
    np.testing.assert_array_equal(out[0]["gap"], out[1]["gap"])


def test_grouped_and_segments_label_their_units():
    g = rd.grouped(np.random.default_rng(2))
    assert len(set(info(g.a, "driver"))) == 8 and g.group_by == "driver"
    assert not set(info(g.a, "driver")) & set(info(g.b, "driver"))
    s = rd.segments(np.random.default_rng(3))
    assert s.a.n_runs == 80 and len(set(info(s.a, "run"))) == 20
    assert s.a.run_ids[:2] == ("a000.s0", "a000.s1")
    # consecutive segments of one run continue each other
    first, second = s.a.run(0), s.a.run(1)
    assert second["t"][0] == pytest.approx(first["t"][-1] + rd.DT)


def test_lengths_has_a_start_transient():
    d = rd.lengths(np.random.default_rng(4))
    assert set(d.a.lengths) == {10} and set(d.b.lengths) == {100}
    ratio = lambda ts, k: np.abs(np.log(ts.column("gap").reshape(ts.n_runs, -1)[:, k]  # noqa
                                        / rd.equilibrium_gap(ts.column("v").reshape(
                                            ts.n_runs, -1)[:, k])))
    assert ratio(d.b, 0).mean() > 2 * ratio(d.b, 99).mean()


@pytest.mark.parametrize("kind", rd.DEFECTS)
@pytest.mark.parametrize("paired", [True, False])
def test_defects(kind, paired):
    d = rd.defect(np.random.default_rng(7), kind, paired=paired)
    assert (d.a.run_ids == d.b.run_ids) == paired
    assert d.pair_by == ("run_id" if paired else None)
    if paired:  # same scenarios
        np.testing.assert_array_equal(d.a.column("v_leader"), d.b.column("v_leader"))
    if kind == "clip":
        lo, hi = np.quantile(d.a.column("a"), [0.075, 0.925])
        assert d.b.column("a").min() >= lo - 1e-12 and d.b.column("a").max() <= hi + 1e-12
    if kind == "gap_gain":  # recorded gap steps = 0.9 × the kinematic ones (the truth's)
        gap, v, vl = (d.b.column(c).reshape(len(d.b.run_ids), -1)
                      for c in ("gap", "v", "v_leader"))
        step = (vl[:, :-1] - 0.5 * (v[:, :-1] + v[:, 1:])) * rd.DT
        np.testing.assert_allclose(np.diff(gap, axis=1), 0.9 * step, atol=1e-9)
    if kind.startswith("late_brake"):
        share = 0.1 if kind.endswith("10") else 0.5
        assert np.mean(np.array(info(d.b, "late")) > 0) == share
    with pytest.raises(ValueError):
        rd.defect(np.random.default_rng(0), "nonsense")
