"""The car-following study on the per-region engine: options, a small end-to-end run, the same
cell result as validate for the same inputs, files and CLI."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from simcred.compare import Method
from simcred.errors import OptionError
from simcred.io.openacc import HUMAN, read_openacc
from simcred.regions import CellStatus
from simcred.sim.sumo import replay
from simcred.study.car_following import (
    BASELINE,
    BASELINE_CARS,
    REAL_ACC,
    StudyOptions,
    _subset,
    repeat_baselines,
    run_study,
)
from simcred.study.files import write_study

SMALL = dict(models=("IDM",), max_episodes=80, permutations=99, min_runs=5, seed=3)
BANDS = ((0.0, 10.0), (10.0, 20.0), (20.0, 30.0))


@pytest.fixture(scope="module")
def small():
    return run_study(StudyOptions(**SMALL))


@pytest.fixture(scope="module")
def judged():
    return run_study(StudyOptions(**SMALL, tolerance={"v": 0.1}))


@pytest.mark.parametrize("kwargs", [{"bands": ((10, 0),)}, {"bands": ((0, 10), (5, 15))},
                                    {"bands": ((0, 10), (20, 30))}, {"models": ()},
                                    {"permutations": 5}, {"alpha": 1.5}, {"bins": 1},
                                    {"max_episodes": 1}, {"bands": ((0, float("inf")),)},
                                    {"bootstrap": 10}, {"sample_step": 0},
                                    {"features": ("gap", "x")}, {"inputs": ("a",)},
                                    {"inputs": ("gap", "v", "v_leader")},
                                    {"tolerance": {"v_leader": 0.1}}, {"tolerance": {"v": -1}},
                                    {"min_runs": 1}, {"seed": -1}, {"alpha": "x"},
                                    {"bins": (3, 4)}, {"sample_step": None},
                                    {"features": ("gap", "gap")}, {"permutations": 0},
                                    {"seed": np.random.default_rng(0)}])
def test_bad_options(kwargs):
    with pytest.raises(OptionError):
        StudyOptions(**kwargs)


@pytest.mark.parametrize(("kwargs", "method"), [
    ({"alpha": 1.5}, {"alpha": 1.5}), ({"alpha": "x"}, {"alpha": "x"}),
    ({"sample_step": 0}, {"resample": 0}), ({"seed": 1.5}, {"seed": 1.5}),
    ({"permutations": 2.5}, {"permutations": 2.5}),
    ({"features": ("gap", "gap")}, {"features": ("gap", "gap")})])
def test_comparison_options_are_checked_by_method(kwargs, method):
    """One place: the study's comparison options fail with Method's own message."""
    with pytest.raises(OptionError) as expected:
        Method(test="response", **method)
    with pytest.raises(OptionError, match=f"^{re.escape(str(expected.value))}$"):
        StudyOptions(**kwargs)


@pytest.mark.parametrize(("kwargs", "needle"), [
    ({"inputs": ("a",)}, "input 'a' is not one of the features"),  # compare's own checks
    ({"inputs": ("gap", "v", "v_leader")}, "every feature is declared an input"),
    ({"bins": 1}, "bins must be integers >= 2"), ({"bins": (3, 4)}, "bins gives 2 values"),
    ({"permutations": 0}, "permutations must be at least 19"),  # the study's least sizes
    ({"bootstrap": -1}, "bootstrap must be at least 100"),
    ({"features": ("gap", "x")}, "unknown feature(s) x"),
    ({"seed": np.random.default_rng(0)}, "seeds the SUMO replays")])
def test_study_messages(kwargs, needle):
    with pytest.raises(OptionError, match=re.escape(needle)):
        StudyOptions(**kwargs)


def test_bands_are_one_grid_over_the_leader_speed():
    grid = StudyOptions().grid()
    assert grid.variables == ("v_leader",) and grid.edges == ((0.0, 10.0, 20.0, 30.0),)
    assert grid.units == ("m/s",)


def test_small_study(small):
    assert small.rows == (BASELINE, BASELINE_CARS, "SUMO IDM", REAL_ACC)
    assert len(small.cells) == 4 * 3
    assert [c.band for c in small.cells[:4]] == [BANDS[0]] * 4  # band by band, rows in order
    top = [c for c in small.cells if c.band == BANDS[2]]
    assert {c.status for c in top} == {CellStatus.UNKNOWN}  # no human episode at 20-30 m/s
    assert "reference has 0 units" in top[0].result.reason
    compared = [c for c in small.cells if c.compared]
    assert {c.row for c in compared} == set(small.rows)
    for c in compared:  # no tolerance: deviations reported, never judged
        r = c.result
        assert c.status is CellStatus.COMPARED and 0 < r.pvalue <= 1
        assert [b.feature for b in r.bounds] == ["gap", "v"]
        assert all(b.tolerance is None and 0 <= b.low <= b.high for b in r.bounds)
        assert r.comparison.options.test == "response"
    design = {c.row: c.result.design for c in compared}
    assert design["SUMO IDM"] == "pairs by run" and design[REAL_ACC] == "groups by run"
    assert design[BASELINE] == design[BASELINE_CARS] == "groups by run"
    doc = small.to_dict()
    assert "response comparison" in doc["method"] and doc["options"]["tolerance"] == {}
    assert doc["inputs"]["versions"]["sumo"] and len(doc["inputs"]["files"]) == 38
    assert doc["inputs"]["seeds"]["study"] == 3 and doc["inputs"]["seeds"]["sumo"] == 3
    assert len(doc["findings"]) == len(small.cells)
    assert not any("valid" in f for f in doc["findings"])


def test_baselines_split_whole_units():
    """The car split puts every car's segments in one half; the random split every episode's."""
    from simcred.compare.design import unit_keys
    from simcred.regions import SOURCE_RUN, halves
    from simcred.study.car_following import CAR

    options = StudyOptions(**SMALL)
    human = _subset(read_openacc(None, options.rules, follower=HUMAN), options.max_episodes)
    cell = options.settings().segments(human, options.grid()).by_cell[1]
    for key in (CAR, SOURCE_RUN):
        a, b = halves(cell, key, 0)
        keys_a, keys_b = set(unit_keys(a, key, "g")), set(unit_keys(b, key, "g"))
        assert not keys_a & keys_b and keys_a | keys_b == set(unit_keys(cell, key, "g"))
        assert a.n_runs + b.n_runs == cell.n_runs and abs(len(keys_a) - len(keys_b)) <= 1


def test_same_seed_same_findings(small):
    assert run_study(StudyOptions(**SMALL)).to_json() == small.to_json()


def test_a_tolerance_decides_the_cells(judged):
    compared = [c for c in judged.cells if c.compared]
    assert compared
    for c in compared:
        assert c.status in (CellStatus.VALID, CellStatus.NOT_VALID, CellStatus.INCONCLUSIVE)
        v = next(b for b in c.result.bounds if b.feature == "v")
        gap = next(b for b in c.result.bounds if b.feature == "gap")
        assert v.tolerance == 0.1 and gap.tolerance is None  # gap reported, not judged
    # IDM's acceleration response deviates far beyond 0.1 m/s² at 10-20 m/s
    assert judged.cell("SUMO IDM", BANDS[1]).status is CellStatus.NOT_VALID
    assert judged.to_dict()["options"]["tolerance"] == {"v": 0.1}


def test_study_and_validate_give_the_same_cell_results(judged):
    """One engine: the study's SUMO row is exactly validate's domain of the same replays with
    the same settings (a validation file with the study's values), cell by cell."""
    from simcred.validate.cells import grid_of, segments
    from simcred.validate.domain import cell_rule, learn_domain
    from simcred.validate.spec import parse_validation

    options = judged.options
    human = _subset(read_openacc(None, options.rules, follower=HUMAN), options.max_episodes)
    idm = replay(human, ["IDM"], seed=options.seed)["IDM"]
    spec = parse_validation({
        "test_case": {"conditions": "0 <= v_leader <= 30", "tolerance": {"v": 0.1}},
        "reference": {"path": "human.parquet"},
        "candidates": {"idm": {"runs": {"path": "idm.parquet"}}},
        "features": ["gap", "v", "v_leader"], "inputs": ["v_leader"],
        "conditions": {"v_leader": {"unit": "m/s", "edges": [0, 10, 20, 30]}},
        "comparison": {"bins": 3, "alpha": 0.05, "permutations": 99, "bootstrap": 500,
                       "seed": 3, "resample": 0.5},
        "min_data": {"runs": 5, "samples": 500}, "segments": {"min_length": 25}})
    grid = grid_of(spec.conditions)
    assert grid == options.grid()
    reference = segments(human, grid, spec.segments.min_length)
    domain = learn_domain(spec, grid, reference, idm, "SUMO IDM",
                          cell_rule(spec, grid.n_cells, replay=True))
    study = [judged.cell("SUMO IDM", band).result for band in BANDS]
    for mine, theirs in zip(study, domain.cells, strict=True):
        a, b = mine.to_dict(), theirs.to_dict()
        # validate reports the judged feature only; the study every response feature
        assert [d for d in a["deviation"] if d["feature"] == "v"] == b["deviation"]
        assert {k: v for k, v in a.items() if k != "deviation"} == \
            {k: v for k, v in b.items() if k != "deviation"}
    assert any(c.status is not CellStatus.UNKNOWN for c in domain.cells)


def test_write_and_cli(small, tmp_path, capsys):
    from simcred.cli import run

    paths = write_study(small, tmp_path / "w")
    doc = json.loads((tmp_path / "w" / "study.json").read_text())
    assert doc["kind"] == "car_following_study" and paths[0].name == "study.json"
    matrix = (tmp_path / "w" / "matrix.csv").read_text().splitlines()
    assert matrix[0] == "row,0-10 m/s,10-20 m/s,20-30 m/s" and len(matrix) == 5
    assert "v=" in matrix[3] and "p=" in matrix[3] and matrix[3].endswith("unknown")
    band = (tmp_path / "w" / "bands" / "10-20_m_s.csv").read_text().splitlines()
    assert "v_deviation_mps2" in band[0] and "gap_deviation_mps" in band[0]
    code = run(["--quiet", "study", "car-following", "--out", str(tmp_path / "c"), "--models",
                "IDM", "--max-episodes", "40", "--permutations", "99", "--min-runs", "5",
                "--bands", "0-10,10-20", "--tolerance", "v=0.1"])
    assert code == 0
    assert (tmp_path / "c" / "matrix.png").is_file() and (tmp_path / "c" / "maps").is_dir()
    cli_doc = json.loads((tmp_path / "c" / "study.json").read_text())
    assert cli_doc["options"]["tolerance"] == {"v": 0.1}
    assert run(["study", "car-following", "--out", str(tmp_path / "c")]) == 2  # no clobbering
    assert "--overwrite" in capsys.readouterr().err
    assert run(["study", "car-following", "--out", str(tmp_path / "d"), "--bands", "0..10"]) == 2
    assert "LOW-HIGH" in capsys.readouterr().err
    for removed in (["--test", "runs"], ["--one-sided", "neutral"], ["--baseline", "10"]):
        assert run(["study", "car-following", "--out", str(tmp_path / "d"), *removed]) == 2
        err = capsys.readouterr().err
        assert f"{removed[0]} was removed" in err and len(err.strip().splitlines()) == 1
    assert run(["study", "car-following", "--out", str(tmp_path / "d"), "--tolerance", "v"]) == 2
    assert "FEATURE=NUMBER" in capsys.readouterr().err


@pytest.mark.parametrize("command", [["study", "car-following"], ["simulate", "sumo-following"],
                                     ["data", "openacc"]])
def test_help_shows_units(command, capsys):
    from simcred.cli import run

    assert run([*command, "--help"]) == 0
    text = capsys.readouterr().out
    assert "[m/s]" in text and "[m]" in text


def test_repeat_baselines_are_the_study_cells(small):
    cells = repeat_baselines([SMALL["seed"]], StudyOptions(**SMALL))
    assert len(cells) == 2 * 3
    for c in cells:
        assert c.result.to_dict() == small.cell(c.row, c.band).result.to_dict()


@pytest.mark.slow
def test_random_human_split_rejected_about_alpha_or_less():
    """False rejections of the difference test on real data (H0 true by construction: random
    halves of the same human episodes), 20 seeds × 2 bands at alpha = 0.05. Expected 2
    rejections; 6 or more has probability < 0.02 for a test at its level."""
    options = StudyOptions(permutations=99, bootstrap=100)
    cells = [c for c in repeat_baselines(range(2000, 2020), options)
             if c.row == BASELINE and c.compared]
    assert len(cells) == 40
    assert sum(c.result.pvalue <= 0.05 for c in cells) <= 5


def test_csv_fields_round_trip_through_the_csv_module():
    import csv
    import io

    from simcred.study.files import _csv

    texts = ["plain", 'say "hi", twice', "a,b", ""]
    line = ",".join(_csv(t) for t in texts)
    assert next(csv.reader(io.StringIO(line))) == texts


def test_segments_of_one_episode_are_one_unit(small):
    """Episodes are cut at band edges: an episode whose leader crosses 10 m/s has a segment in
    both bands, and within a band the design counts episodes, not segments."""
    per_band = small.episodes["human"]["per_band"]
    assert per_band[0]["segments"] >= per_band[0]["episodes"]
    r = small.cell(BASELINE, BANDS[1]).result
    assert r.reference_units + r.candidate_units == per_band[1]["episodes"]
    assert np.isfinite(r.bounds[0].estimate)
