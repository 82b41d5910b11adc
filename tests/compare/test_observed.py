"""The observation-model route of issue 23: a sensor model, its estimation, the comparison with
an observed side, and the CLI (docs/observed.md)."""

from __future__ import annotations

import json

import numpy as np
import pytest

import observed_universe as universe
from simcred.cli import run
from simcred.compare import compare
from simcred.compare.observed import (
    SensorModel,
    SignalSensor,
    compare_observed,
    crop,
    estimate_sensor,
    observe,
)
from simcred.errors import OptionError
from simcred.seeds import stream
from simcred.traces import TraceSet

OPTIONS = {"features": ["u", "v"], "bins": 4, "alpha": 0.05, "permutations": 99,
           "multiplicity": "fwer"}


def ramp(runs: int = 2, steps: int = 8, dt: float = 0.1) -> TraceSet:
    return TraceSet.from_runs([{"t": np.arange(steps) * dt, "x": np.arange(steps) + 100.0 * i,
                                "y": -np.arange(steps, dtype=float)} for i in range(runs)])


def test_observe_shifts_offsets_and_crops_exactly():
    ts = ramp()
    seen = observe(ts, SensorModel({"x": SignalSensor(offset=0.5, delay=0.2)}))
    assert seen.lengths.tolist() == [6, 6]
    run0 = seen.run(0)
    assert run0["x"].tolist() == [0.5, 1.5, 2.5, 3.5, 4.5, 5.5]  # x_{t-2} + 0.5 at t = 2..7
    assert run0["y"].tolist() == [-2.0, -3.0, -4.0, -5.0, -6.0, -7.0]  # untouched, cropped
    assert np.allclose(run0["t"], np.arange(2, 8) * 0.1)


def test_dropouts_hold_the_last_value_at_the_declared_rate():
    ts = TraceSet.from_runs([{"t": np.arange(4000) * 0.1, "x": np.arange(4000.0)}])
    x = observe(ts, SensorModel({"x": SignalSensor(dropout=0.2)}), seed=3).column("x")
    held = np.diff(x) == 0
    assert x[0] == 0 and np.all(np.diff(x) >= 0)  # never ahead of the truth, never back
    assert abs(held.mean() - 0.2) < 0.03  # binomial sd 0.006
    fresh = np.flatnonzero(~np.r_[False, held])
    assert np.array_equal(x[fresh], fresh.astype(float))  # a fresh sample is the true one


def test_noise_sd_is_the_declared_one():
    ts = TraceSet.from_runs([{"t": np.arange(5000) * 0.1, "x": np.zeros(5000)}])
    x = observe(ts, SensorModel({"x": SignalSensor(noise_sd=0.3)}), seed=1).column("x")
    assert abs(x.std() - 0.3) < 0.015 and abs(x.mean()) < 0.015


def test_estimate_recovers_the_universe_sensor_with_spread():
    gt, sd = universe.calibration_pairs(np.random.default_rng(5), 20, 100)
    model = estimate_sensor(gt, sd, bootstrap=20, seed=1)
    for name in ("u", "v"):
        s, true = model.signals[name], universe.SENSOR.signals[name]
        assert s.delay == pytest.approx(true.delay)
        assert s.offset == pytest.approx(true.offset, abs=0.03)  # se ≈ 0.006
        assert s.noise_sd == pytest.approx(true.noise_sd, abs=0.02)
        assert s.dropout == pytest.approx(true.dropout, abs=0.02)
        offsets = [d[name].offset for d in model.draws]
        assert 0.001 < np.std(offsets) < 0.03
    again = SensorModel.from_dict(json.loads(json.dumps(model.to_dict())))
    assert again.signals == model.signals and len(again.draws) == 20


@pytest.mark.parametrize(("change", "message"), [
    (lambda gt, sd: (crop(gt, 0), sd), None),
    (lambda gt, sd: (TraceSet.from_runs([gt.run(0)]), sd), "at least 2 paired runs"),
    (lambda gt, sd: (gt, TraceSet.from_runs([sd.run(0), sd.run(1)], run_ids=["0", "9"])),
     "no recording of run '1'"),
])
def test_estimate_refuses_what_it_cannot_pair(change, message):
    gt, sd = universe.calibration_pairs(np.random.default_rng(5), 3, 30)
    truth, recorded = change(gt, sd)
    if message is None:
        estimate_sensor(truth, recorded, bootstrap=0)
        return
    with pytest.raises(OptionError, match=message):
        estimate_sensor(truth, recorded, bootstrap=0)


def test_bad_models_and_sides_are_one_line_errors():
    with pytest.raises(OptionError, match="dropout must be in"):
        SignalSensor(dropout=1.0)
    with pytest.raises(OptionError, match="unknown sensor field"):
        SensorModel.from_dict({"x": {"lag": 1}})
    with pytest.raises(OptionError, match="does not have"):
        observe(ramp(), SensorModel({"speed": SignalSensor()}))
    with pytest.raises(OptionError, match="too few for the sensor delay"):
        observe(ramp(steps=3), SensorModel({"x": SignalSensor(delay=0.2)}))
    with pytest.raises(OptionError, match="observed must be"):
        compare_observed(ramp(), ramp(), observed="c", sensor=SensorModel({"x": SignalSensor()}))


def test_a_recording_that_never_changes_is_named_not_a_full_dropout_model():
    runs = [{"t": np.arange(6) * 0.1, "x": np.arange(6.0), "v": np.full(6, 3.0)}
            for _ in range(3)]
    truth, recorded = TraceSet.from_runs(runs), TraceSet.from_runs(runs)
    with pytest.raises(OptionError, match="signal 'v': its recording never changes"):
        estimate_sensor(truth, recorded, bootstrap=0)
    assert estimate_sensor(truth, recorded, signals=["x"], bootstrap=0).signals["x"].dropout == 0


def test_direct_comparison_sees_the_sensor_the_observed_one_keeps_the_level():
    """Seeded small version of scripts/observed_study.py (H0): the recording is the simulated
    process seen through the sensor. Oracle: the direct test rejects nearly always, the observed
    route at most at a rate compatible with α = 0.05 (40 reps: P(≥ 6 | 0.05) ≈ 0.05 for an exact
    test; a route that ignored the delay or the dropouts rejects almost always)."""
    direct = observed = 0
    for rep in range(40):
        rng = stream(2023, rep)
        sim, rec = universe.truth(rng, 50, 80), universe.recording(rng, 50, 80)
        direct += compare(sim, rec, seed=rep, **OPTIONS).chain.rejected
        observed += compare_observed(sim, rec, observed="b", sensor=universe.SENSOR, seed=rep,
                                     **OPTIONS).rejected
    assert direct >= 36
    assert observed <= 6


def test_observed_route_finds_a_changed_reaction_delay():
    """Reaction delay 1.0 s recorded, 0.5 s simulated: rejected far more often than a level-α
    test would by chance (P(≥ 4 of 10 | 0.05) ≈ 0.001); the power itself is measured by
    scripts/observed_study.py at 60 runs × 100 steps."""
    hits = 0
    for rep in range(10):
        rng = stream(77, rep)
        sim, rec = universe.truth(rng, 50, 80), universe.recording(rng, 50, 80, reaction=10)
        hits += compare_observed(sim, rec, observed="b", sensor=universe.SENSOR, seed=rep,
                                 **OPTIONS).rejected
    assert hits >= 4


def test_observed_side_a_is_symmetric():
    rng = stream(3, 0)
    sim, rec = universe.truth(rng, 30, 60), universe.recording(rng, 30, 60)
    ab = compare_observed(sim, rec, observed="b", sensor=universe.SENSOR, seed=4, **OPTIONS)
    ba = compare_observed(rec, sim, observed="a", sensor=universe.SENSOR, seed=4, **OPTIONS)
    assert ab.cropped == ba.cropped == 3
    assert ab.comparison.inputs[1].rows == ba.comparison.inputs[0].rows == 30 * 57


def test_cli_observed_and_estimate_sensor(tmp_path, capsys):
    rng = stream(9, 0)
    gt, sd = universe.calibration_pairs(rng, 10, 60)
    sim, rec = universe.truth(rng, 30, 60), universe.recording(rng, 30, 60)
    paths = {name: ts.write(tmp_path / f"{name}.parquet")
             for name, ts in (("gt", gt), ("sd", sd), ("sim", sim), ("rec", rec))}
    model = tmp_path / "sensor.json"
    assert run(["estimate-sensor", str(paths["gt"]), str(paths["sd"]), "--out", str(model),
                "--bootstrap", "5", "--seed", "1"]) == 0
    assert len(json.loads(model.read_text())["draws"]) == 5
    capsys.readouterr()
    assert run(["compare", str(paths["sim"]), str(paths["rec"]), "-f", "u,v", "--bins", "4",
                "--permutations", "99", "--seed", "2", "--observed", "b", "--sensor", str(model),
                "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["observed"] == "b" and doc["cropped"] == 3 and doc["sensor_effect"] is not None
    assert run(["compare", str(paths["sim"]), str(paths["rec"]), "--observed", "b"]) == 2
    assert "--observed goes with one of --sensor" in capsys.readouterr().err
    bad = tmp_path / "bad.json"
    bad.write_text('{"u": {"dropout": 2}}')
    assert run(["compare", str(paths["sim"]), str(paths["rec"]), "--observed", "a",
                "--sensor", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "dropout must be in" in err[0]
