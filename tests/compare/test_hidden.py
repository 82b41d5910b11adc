"""Path b (issue 23): the HMM forward–backward against brute-force enumeration, Baum–Welch with
fixed emissions against a known chain, and compare_hidden's refusals and level."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

import observed_universe as universe
from simcred.compare.hidden import _simulate, baum_welch, compare_hidden, forward_backward
from simcred.errors import OptionError
from simcred.seeds import stream
from simcred.traces import TraceSet


def test_forward_backward_matches_enumeration_of_all_paths():
    rng = np.random.default_rng(0)
    A = rng.dirichlet(np.ones(3), size=3)
    pi = rng.dirichlet(np.ones(3))
    B = rng.dirichlet(np.ones(2), size=3)
    obs = np.array([[0, 1, -1, 1, 0], [1, 1, 0, -1, -1]])  # −1: missing
    start = np.zeros(3)
    xi = np.zeros((3, 3))
    visits = np.zeros(3)
    loglik = 0.0
    for run in obs:
        paths = list(itertools.product(range(3), repeat=len(run)))
        weights = np.array([pi[p[0]] * np.prod([A[p[t - 1], p[t]] for t in range(1, len(p))])
                            * np.prod([B[p[t], o] for t, o in enumerate(run) if o >= 0])
                            for p in paths])
        loglik += np.log(weights.sum())
        post = weights / weights.sum()
        for w, p in zip(post, paths, strict=True):
            start[p[0]] += w
            for t in range(len(p)):
                visits[p[t]] += w
                if t:
                    xi[p[t - 1], p[t]] += w
    like = np.where((obs >= 0)[..., None], B.T[np.maximum(obs, 0)], 1.0)[None]
    s, x, g, ll = forward_backward(like, A[None], pi[None])
    assert np.allclose(s[0], start) and np.allclose(x[0], xi) and np.allclose(g[0], visits)
    assert ll[0] == pytest.approx(loglik)


def test_baum_welch_with_fixed_emissions_recovers_the_chain():
    rng = np.random.default_rng(1)
    A = np.array([[0.8, 0.15, 0.05], [0.1, 0.8, 0.1], [0.05, 0.25, 0.7]])
    B = np.array([[0.7, 0.2, 0.1], [0.15, 0.7, 0.15], [0.1, 0.2, 0.7]])
    hidden = _simulate(rng, A, np.full(3, 1 / 3), [200] * 100)
    cum = np.cumsum(B, axis=1)
    obs = [np.minimum((cum[h] < rng.random(len(h))[:, None]).sum(axis=1), 2) for h in hidden]
    for o in obs:
        o[rng.random(len(o)) < 0.1] = -1
    A_hat, *_ = baum_welch([obs], B[None], np.ones(3, bool))
    assert np.abs(A_hat[0] - A).max() < 0.05  # 20,000 steps: se of an entry ≈ 0.005–0.01


def test_compare_hidden_refuses_what_it_cannot_estimate():
    rng = stream(4, 0)
    sim, rec = universe.truth(rng, 20, 60), universe.recording(rng, 20, 60)
    gt, sd = universe.calibration_pairs(rng, 3, 60)
    one = (TraceSet.from_runs([gt.run(0)]), TraceSet.from_runs([sd.run(0)]))
    with pytest.raises(OptionError, match="at least 2 paired runs"):
        compare_hidden(sim, rec, observed="b", calibration=one, features=["v"])
    with pytest.raises(OptionError, match="never observed in the calibration runs"):
        compare_hidden(sim, rec, observed="b", calibration=(gt, sd), features=["u", "v"],
                       bins=8)
    with pytest.raises(OptionError, match="observed must be"):
        compare_hidden(sim, rec, observed="x", calibration=(gt, sd), features=["v"])


@pytest.mark.slow
def test_compare_hidden_keeps_the_level_and_sees_the_reaction_delay():
    """Seeded small version of scripts/hidden_study.py: 12 H0 replications, at most 3
    rejections at α = 0.05 (P(≥ 4 | 0.05) ≈ 0.002 for an exact test); and the recorded
    reaction delay of 1.0 s (0.5 s simulated) rejected in most of 6 replications."""
    def run(rep, **law):
        rng = stream(99, rep)
        sim = universe.truth(rng, 40, 80)
        rec = universe.recording(rng, 40, 80, **law)
        cal = universe.calibration_pairs(rng, 20, 80)
        return compare_hidden(sim, rec, observed="b", calibration=cal, features=["v"], bins=5,
                              n_resamples=19, seed=rep)
    assert sum(run(rep).rejected for rep in range(12)) <= 3
    first = run(0)
    assert first.lags == (3,) and 0.03 < first.dropout < 0.08
    assert sum(run(100 + rep, reaction=10).rejected for rep in range(6)) >= 4


def test_cli_path_b_and_its_one_line_refusals(tmp_path, capsys):
    from simcred.cli import run

    rng = stream(6, 0)
    gt, sd = universe.calibration_pairs(rng, 10, 60)
    sim, rec = universe.truth(rng, 20, 60), universe.recording(rng, 20, 60)
    p = {name: ts.write(tmp_path / f"{name}.parquet")
         for name, ts in (("gt", gt), ("sd", sd), ("sim", sim), ("rec", rec))}
    base = ["compare", str(p["sim"]), str(p["rec"]), "--observed", "b", "--calibration",
            f"{p['gt']},{p['sd']}", "--permutations", "9", "--seed", "1"]
    assert run([*base, "-f", "v", "--bins", "3", "--json"]) == 0
    assert '"method": "hmm"' in capsys.readouterr().out
    assert run([*base, "-f", "u,v", "--bins", "9"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "never observed in the calibration runs" in err[0]
    assert run([*base, "-f", "v", "--sensor", str(tmp_path / "x.json")]) == 2
    assert "one of --sensor" in capsys.readouterr().err


#: compare_hidden on a fixed seed before the time-major forward–backward (commit 071f03b):
#: the p-value, statistic, fitted hidden transitions and bootstrap null, to the last bits
OLD_PVALUE, OLD_STATISTIC = 0.95, 0.015585197404155466
OLD_TRANSITIONS = [
    0.9743839020057686, 0.025616097992929715, 1.3017118876996062e-12, 8.237548598703114e-20,
    0.03596339362194401, 0.9124883904362938, 0.05154821592457718, 1.7184987817922157e-11,
    2.5801179555321445e-11, 0.05306854316088282, 0.9029555091774275, 0.04397594763588847,
    6.137357098745828e-22, 3.1727542382582315e-13, 0.04841021614706927, 0.9515897838526135,
]
OLD_NULL = [
    0.02561065885090285, 0.022220020225960525, 0.02346455877072343, 0.03031927918657949,
    0.029804706744237724, 0.02897637095640971, 0.036865730170349456, 0.02162925409508276,
    0.02100772872811288, 0.02706635292506318, 0.020692722224363747, 0.02084714351413238,
    0.010607330991792367, 0.021547915729236918, 0.02242884286525825, 0.04445489631065635,
    0.02940378910559613, 0.016385821764721985, 0.032920642281781994,
]


def test_compare_hidden_equals_the_code_before_the_speedup():
    rng = stream(7, 0)
    sim, rec = universe.truth(rng, 40, 80), universe.recording(rng, 40, 80)
    cal = universe.calibration_pairs(rng, 20, 80)
    r = compare_hidden(sim, rec, observed="b", calibration=cal, features=["v"], bins=4,
                       n_resamples=19, seed=3)
    assert r.pvalue == OLD_PVALUE
    assert r.statistic == pytest.approx(OLD_STATISTIC, rel=1e-12)
    assert np.allclose(r.transitions_observed.ravel(), OLD_TRANSITIONS, rtol=1e-12, atol=1e-15)
    assert np.allclose(r.null_distribution, OLD_NULL, rtol=1e-12, atol=0)


def test_hidden_document_keeps_its_keys_and_order():
    """The document comes from the fields (``simcred._json.fields_dict``, issue 27): the keys
    and order it always had, no arrays."""
    import numpy as np

    from simcred.compare.hidden import HiddenComparison

    empty = np.zeros(0)
    result = HiddenComparison(0.5, 0.2, 0.05, False, 99, "b", 3, (1, 2), 0.1, 0.6, 0.7,
                              empty, empty, empty, empty)
    assert result.to_dict() == {
        "method": "hmm", "statistic": 0.5, "pvalue": 0.2, "alpha": 0.05, "rejected": False,
        "n_resamples": 99, "observed": "b", "n_states": 3, "lags": [1, 2], "dropout": 0.1,
        "markov_pvalue": 0.6, "emission_pvalue": 0.7}
    assert list(result.to_dict())[:3] == ["method", "statistic", "pvalue"]
