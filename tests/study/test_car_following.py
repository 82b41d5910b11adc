"""The car-following study: verdict combination, bands, thinning, a small end-to-end run, CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.stats import combine_pvalues

from helpers import ar_set
from simcred.compare import compare
from simcred.errors import OptionError
from simcred.study.car_following import (
    BASELINE,
    BASELINE_CARS,
    REAL_ACC,
    StudyOptions,
    band_index,
    repeat_baselines,
    run_study,
    thin,
)
from simcred.study.files import write_study
from simcred.study.verdict import chain_verdict, fisher
from simcred.traces import TraceSet

SMALL = dict(models=("IDM",), max_episodes=80, permutations=99, min_runs=5, seed=3)


@pytest.fixture(scope="module")
def small():
    return run_study(StudyOptions(**SMALL))


def test_fisher_matches_scipy():
    rng = np.random.default_rng(0)
    for k in (1, 3, 40):
        p = list(rng.uniform(0.001, 1, size=k))
        assert fisher(p) == pytest.approx(combine_pvalues(p, method="fisher").pvalue, rel=1e-12)
    assert fisher([]) is None


@pytest.mark.slow
def test_interim_verdict_holds_its_level_on_independent_transitions():
    """H0 true, transitions independent given the state (AR(1) chains, both sets alike): the
    Fisher-combined per-transition test rejects at most about alpha of the time."""
    alpha, reps, rejected = 0.1, 120, 0
    for rep in range(reps):
        rng = np.random.default_rng(rep)
        a, b = ar_set(rng, 40, 0.5, length=12), ar_set(rng, 40, 0.5, length=12)
        result = compare(a, b, bins=3, test="permutation", permutations=199, seed=rep,
                         continue_on_start_difference=True, alpha=alpha)
        rejected += chain_verdict(result, "permutation", alpha).rejected
    assert rejected / reps <= alpha + 3 * np.sqrt(alpha * (1 - alpha) / reps)


def test_interim_verdict_detects_reversed_dynamics():
    rng = np.random.default_rng(1)
    a, b = ar_set(rng, 60, 0.8, length=20), ar_set(rng, 60, -0.8, length=20)
    result = compare(a, b, bins=3, test="permutation", permutations=199, seed=0,
                     continue_on_start_difference=True)
    verdict = chain_verdict(result, "permutation", 0.01)
    assert verdict.rejected and verdict.pvalue < 1e-6 and "Fisher" in verdict.method


def test_band_index_edges():
    runs = [{"t": [0.0, 0.1], "v_leader": [v, v]} for v in (0.0, 9.99, 10.0, 20.0, 30.0, 35.0)]
    ts = TraceSet.from_runs(runs)
    bands = ((0.0, 10.0), (10.0, 20.0), (20.0, 30.0))
    assert band_index(ts, bands).tolist() == [0, 0, 1, 2, 2, -1]


def test_thin_keeps_every_kth_sample():
    ts = TraceSet.from_runs([{"t": np.arange(11) * 0.1, "x": np.arange(11.0)},
                             {"t": np.arange(7) * 0.1, "x": np.arange(7.0) + 100}])
    out = thin(ts, 5)
    assert out.run(0)["x"].tolist() == [0, 5, 10] and out.run(1)["x"].tolist() == [100, 105]


@pytest.mark.parametrize("kwargs", [{"test": "bound"}, {"bands": ((10, 0),)},
                                    {"bands": ((0, 10), (5, 15))}, {"models": ()},
                                    {"sample_step": 0.25}, {"permutations": 49},
                                    {"alpha": 1.5}, {"bins": 1}, {"max_episodes": 1},
                                    {"bands": ((0, float("inf")),)}, {"baseline": -1},
                                    {"test": "per-transition"}, {"one_sided": "ignore"}])
def test_bad_options(kwargs):
    with pytest.raises(OptionError):
        StudyOptions(**kwargs).every  # noqa: B018  (sample step is checked against the rules)


def test_small_study(small):
    assert small.rows == (BASELINE, BASELINE_CARS, "SUMO IDM", REAL_ACC)
    assert len(small.cells) == 4 * 3
    top = [c for c in small.cells if c.band == (20.0, 30.0)]
    assert {c.status for c in top} == {"insufficient data"}  # no human episode at 20-30 m/s
    for c in small.cells:
        if c.verdict is not None:
            assert c.verdict.pvalue is not None and 0 <= c.distance <= 1
            assert c.verdict.rejected == (c.verdict.pvalue <= 0.01)
    doc = small.to_dict()
    assert "run-level" in doc["method"] and doc["options"]["test"] == "runs"
    assert doc["inputs"]["versions"]["sumo"] and len(doc["inputs"]["files"]) == 38
    assert doc["inputs"]["seeds"]["study"] == 3
    assert len(doc["findings"]) == len(small.cells)


def test_same_seed_same_findings(small):
    assert run_study(StudyOptions(**SMALL)).to_json() == small.to_json()


def test_default_verdict_is_the_run_level_chain(small):
    """Each tested cell's verdict is the comparison's chain-level one, its distance counts the
    family-wise (max-T) rejections, and the same-model baseline splits the cell's reference."""
    tested = [c for c in small.cells if c.verdict is not None]
    assert tested
    for c in tested:
        chain, options = c.comparison.chain, c.comparison.options
        assert options.test == "runs" and options.multiplicity == "fwer"
        assert c.verdict.pvalue == chain.pvalue and c.verdict.rejected == chain.rejected
        for s in c.comparison.states:  # max-T: adjusted >= raw; rejected only if adjusted <= α
            assert s.result.adjusted_pvalue >= s.result.pvalue
            assert not s.result.rejected or s.result.adjusted_pvalue <= 0.01
        assert c.distance == len(c.comparison.rejected_states) / c.comparison.n_states
        base = c.comparison.baseline
        assert len(base.distances) == 10 and 0 <= base.low <= base.high <= 1
        assert c.to_dict()["baseline"]["high"] == base.high
        assert c.comparison.inputs[0].runs == c.a.runs  # A (split) is the human reference
    assert any("where halves of the reference give" in f for f in small.findings())


def test_interim_test_is_one_option():
    """test='permutation' keeps the interim per-transition verdict: Fisher's combination of the
    per-state p-values, no multiplicity control, no baseline."""
    result = run_study(StudyOptions(**{**SMALL, "test": "permutation"}))
    assert "per-transition" in result.to_dict()["method"]
    for c in result.cells:
        if c.verdict is not None:
            pvalues = [s.result.pvalue for s in c.comparison.states]
            assert c.verdict.pvalue == fisher(pvalues)
            assert c.comparison.chain is None and c.comparison.baseline is None


def test_write_and_cli(small, tmp_path, capsys):
    from simcred.cli import run

    paths = write_study(small, tmp_path / "w")
    doc = json.loads((tmp_path / "w" / "study.json").read_text())
    assert doc["kind"] == "car_following_study" and paths[0].name == "study.json"
    matrix = (tmp_path / "w" / "matrix.csv").read_text().splitlines()
    assert matrix[0] == "row,0-10 m/s,10-20 m/s,20-30 m/s" and len(matrix) == 5
    code = run(["--quiet", "study", "car-following", "--out", str(tmp_path / "c"), "--models",
                "IDM", "--max-episodes", "40", "--permutations", "99", "--min-runs", "5",
                "--bands", "0-10,10-20"])
    assert code == 0
    assert (tmp_path / "c" / "matrix.png").is_file() and (tmp_path / "c" / "maps").is_dir()
    assert run(["study", "car-following", "--out", str(tmp_path / "c")]) == 2  # no clobbering
    assert "--overwrite" in capsys.readouterr().err
    assert run(["study", "car-following", "--out", str(tmp_path / "d"), "--bands", "0..10"]) == 2
    assert "LOW-HIGH" in capsys.readouterr().err
    assert run(["study", "car-following", "--out", str(tmp_path / "d"), "--test", "bound"]) == 2
    err = capsys.readouterr().err
    assert "test must be one of runs, permutation" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("command", [["study", "car-following"], ["simulate", "sumo-following"],
                                     ["data", "openacc"]])
def test_help_shows_units(command, capsys):
    from simcred.cli import run

    assert run([*command, "--help"]) == 0
    text = capsys.readouterr().out
    assert "[m/s]" in text and "[m]" in text


def test_repeat_baselines_are_the_study_cells(small):
    cells = repeat_baselines([SMALL["seed"]], StudyOptions(**SMALL))
    for c in cells:
        study = small.cell(c.row, c.band)
        assert c.status == study.status
        if c.verdict is not None:
            assert c.verdict == study.verdict and c.distance == study.distance


@pytest.mark.slow
def test_random_human_split_rejected_about_alpha_or_less():
    """False rejections of the run-level test on real data (H0 true by construction: random halves
    of the same human episodes), 20 seeds × 2 bands at alpha = 0.01, 199 permutations. Expected
    0.4 rejections; 3 or more has probability < 0.01 for a test at its level."""
    options = StudyOptions(permutations=199, baseline=0)
    cells = [c for c in repeat_baselines(range(2000, 2020), options)
             if c.row == BASELINE and c.verdict is not None]
    assert len(cells) == 40
    assert sum(c.verdict.rejected for c in cells) <= 2
    assert sum(c.distance > 0 for c in cells) <= 2  # FWER: P(distance > 0) <= alpha


def test_csv_fields_round_trip_through_the_csv_module():
    import csv
    import io

    from simcred.study.files import _csv

    texts = ["plain", 'say "hi", twice', "a,b", ""]
    line = ",".join(_csv(t) for t in texts)
    assert next(csv.reader(io.StringIO(line))) == texts
