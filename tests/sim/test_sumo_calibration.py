"""Calibration of SUMO vType attributes: recovers known parameters, objective, split, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from simcred.errors import OptionError
from simcred.io.openacc import read_openacc
from simcred.sim.sumo import SumoModel, parse_model, replay
from simcred.sim.sumo_calibration import (
    PARAMETERS,
    calibrate,
    episode_errors,
    evaluate,
    halves,
    objective,
)
from simcred.traces import RUN_INFO, TraceSet, take

TRUTH = {"tau": 1.6, "accel": 1.2, "decel": 2.0, "minGap": 1.5}


@pytest.fixture(scope="module")
def human():
    return read_openacc(follower="human")


@pytest.fixture(scope="module")
def leaders(human):
    """12 real episodes spread over the set (recorded leaders, start gaps and speeds)."""
    return take(human, np.linspace(0, human.n_runs - 1, 12).astype(int))


@pytest.fixture(scope="module")
def synthetic(leaders):
    """The "recording": SUMO's IDM with known attributes behind the real leaders."""
    return replay(leaders, [SumoModel("IDM", TRUTH)])["IDM"]


def test_calibration_recovers_known_tau_and_accel(leaders):
    """Two attributes from SUMO's defaults (tau 1 s, accel 2.6 m/s²) back to the truth (tau 1.6,
    accel 1.2; decel and minGap SUMO's): ~45 replays of 12 episodes, ~3 s."""
    truth = {"tau": 1.6, "accel": 1.2}
    recording = replay(leaders, [SumoModel("IDM", truth)])["IDM"]
    result = calibrate(recording, "IDM", ["tau", "accel"])
    assert result.converged
    assert result.fitted == pytest.approx(truth, abs=0.01)
    assert result.before["objective"] > 0.1 > 1e-3 > result.after["objective"]


@pytest.mark.slow
def test_calibration_recovers_known_idm_parameters_from_the_defaults(synthetic):
    """Four attributes from SUMO's defaults (tau 1, accel 2.6, decel 4.5, minGap 2.5) back to the
    truth: ~170 replays of 12 episodes, 10-30 s on 2 shared cores."""
    result = calibrate(synthetic, "IDM", ("tau", "accel", "decel", "minGap"))
    assert result.start.params == {"accel": 2.6, "decel": 4.5, "minGap": 2.5, "tau": 1.0}
    assert result.converged
    for name, value in TRUTH.items():
        assert result.fitted[name] == pytest.approx(value, abs=0.02), name
    assert result.before["objective"] > 0.1
    assert result.after["objective"] < 1e-3
    assert result.after["rmse_gap_m"] < 0.01 and result.after["rmse_v_mps"] < 0.01
    assert result.evaluations <= 200
    # the written model replays to the reported objective
    again = parse_model(result.model_text())
    assert again.params == result.model.params
    assert evaluate(synthetic, again)["objective"] == pytest.approx(result.after["objective"])
    assert result.model_text("+").count("+") == 3
    assert result.to_dict()["fitted"] == result.fitted


def test_calibration_keeps_unfitted_attributes_and_honours_bounds(synthetic):
    """Only tau is fitted, accel etc. stay the model's; a bound below the truth stops at it."""
    model = SumoModel("IDM", {"accel": 1.2, "decel": 2.0, "minGap": 1.5})
    result = calibrate(synthetic, model, ["tau"], bounds={"tau": (0.5, 1.3)}, max_evaluations=40)
    assert result.model.params["accel"] == 1.2 and result.model.params["minGap"] == 1.5
    assert result.fitted["tau"] == pytest.approx(1.3, abs=0.01)
    assert result.after["objective"] < result.before["objective"]


def test_objective_is_zero_for_a_set_against_itself_and_positive_otherwise(leaders, synthetic):
    assert objective(synthetic, synthetic) == 0.0
    errors = episode_errors(leaders, synthetic)
    assert errors.shape == (leaders.n_runs, 4)
    gap = [np.sqrt(np.mean((synthetic.run(i)["gap"] - leaders.run(i)["gap"]) ** 2))
           for i in range(leaders.n_runs)]
    assert np.allclose(errors[:, 0], gap)
    scale = [np.sqrt(np.mean(leaders.run(i)["v"] ** 2)) for i in range(leaders.n_runs)]
    assert np.allclose(errors[:, 3], errors[:, 1] / scale)
    assert objective(leaders, synthetic) == pytest.approx(np.mean(errors[:, 2:].mean(axis=1)))


def test_halves_split_whole_recording_files(human):
    first, second = halves(human, by="file")
    info = human.metadata[RUN_INFO]
    files = [{info[r]["file"] for r in half} for half in (first, second)]
    assert not files[0] & files[1]
    assert sorted(first + second) == sorted(human.run_ids)
    # largest file first, then into the smaller half: 22 (192) + 40 (90) vs 35 (166) + 26 (161)
    assert files[0] == {"no_ACC/handling_part22", "no_ACC/handling_part40"}
    assert (len(first), len(second)) == (282, 327)
    assert halves(human, by="file") == (first, second)


def _runs(groups: list[str]) -> TraceSet:
    t = np.arange(3) * 0.1
    runs = [{"t": t, "gap": np.full(3, 20.0), "v": np.full(3, 10.0), "v_leader": np.full(3, 10.0)}
            for _ in groups]
    ids = [f"r{i}" for i in range(len(groups))]
    info = {r: {"file": g} for r, g in zip(ids, groups, strict=True)}
    return TraceSet.from_runs(runs, run_ids=ids, metadata={RUN_INFO: info})


def test_halves_balance_groups_deterministically():
    first, second = halves(_runs(["a", "b", "b", "c", "c", "c"]))
    assert first == ["r3", "r4", "r5"] and second == ["r0", "r1", "r2"]


@pytest.mark.parametrize("kwargs, match", [
    ({"params": ["foo"]}, "cannot fit vType attribute 'foo'"),
    ({"params": "tau"}, "non-empty list"),
    ({"params": []}, "non-empty list"),
    ({"params": ["tau", "tau"]}, "given twice"),
    ({"params": ["tau"], "bounds": {"tau": (2.0, 1.0)}}, "0 < low < high"),
    ({"params": ["tau"], "bounds": {"tau": (0.0, 1.0)}}, "0 < low < high"),
    ({"params": ["tau"], "bounds": {"tau": (0.5, float("inf"))}}, "finite"),
    ({"params": ["tau"], "bounds": {"tau": "ab"}}, "two numbers"),
    ({"params": ["tau"], "bounds": {"accel": (1.0, 2.0)}}, "not fitted"),
    ({"params": ["tau"], "start": {"tau": 5.0}}, r"start value of tau must be in \[0.5, 3\]"),
    ({"params": ["tau"], "start": {"accel": 1.0}}, "not fitted"),
    ({"params": ["tau"], "max_evaluations": 0}, "max_evaluations must be at least 1"),
    ({"params": ["tau"], "tolerance": -1.0}, "tolerance must be a positive number"),
    ({"model": "Foo", "params": ["tau"]}, "must be one of"),
])
def test_bad_input_is_one_line_option_error(synthetic, kwargs, match):
    kwargs = {"model": "IDM", **kwargs}
    with pytest.raises(OptionError, match=match) as caught:
        calibrate(synthetic, **kwargs)
    assert "\n" not in str(caught.value)


def test_bad_sets_are_one_line_option_errors(leaders, synthetic):
    with pytest.raises(OptionError, match="runs differ"):
        episode_errors(leaders, take(synthetic, [0, 1]))
    stopped = _runs(["a"])
    zero = TraceSet.from_runs([{"t": np.arange(3) * 0.1, "gap": np.full(3, 20.0),
                                "v": np.zeros(3), "v_leader": np.zeros(3)}], run_ids=["r0"])
    with pytest.raises(OptionError, match="run 'r0': recorded v is zero throughout"):
        episode_errors(zero, stopped)
    with pytest.raises(OptionError, match="all episodes share one 'file'"):
        halves(_runs(["a", "a"]))
    with pytest.raises(OptionError, match="has no 'driver'"):
        halves(_runs(["a", "b"]), by="driver")
    with pytest.raises(OptionError, match="no run_info"):
        halves(TraceSet.from_runs([{"t": np.arange(2.0), "gap": np.ones(2)}]))


def test_default_bounds_hold_the_sumo_defaults():
    for name, ((lo, hi), default, _, _) in PARAMETERS.items():
        assert lo < default < hi, name
