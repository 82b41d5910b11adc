"""An observed reference in validate (issue 23, item 3): the reference is a sensor's recording
of the candidate's own process (tests/observed_universe.py: bias 0.3, delay 0.3 s, noise 0.25,
5 % dropouts held, on ``u`` and ``v``). Declared observed, the cell is not NOT VALID more often
than α allows, where the direct validation flags it; a real reaction delay in the candidate is
still found; verdict.json and the report say what was compared, the sensor model and what the
sensor alone does; bad declarations are one line, exit 2, naming the key.

Measured at scale by scripts/observed_validate.py (docs/observed.md, "In validate")."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

import observed_universe as universe
from simcred.cli import run
from simcred.compare.observed import estimate_sensor
from simcred.validate.loop import Inputs, validate

RUNS, STEPS = 60, 100


def _verdicts(seeds: range, **law: float) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {"direct": [], "observed": []}
    for seed in seeds:
        rng = np.random.default_rng([23, seed])
        candidate = universe.truth(rng, RUNS, STEPS, **law)
        reference = universe.recording(rng, RUNS, STEPS)
        for route, sensor in (("direct", None), ("observed", universe.SENSOR)):
            spec = universe.validation(seed, sensor=sensor)
            result = validate(spec, Inputs(reference, {"sim": candidate}, (), sensor=sensor))
            out[route].append(result.candidates["sim"].verdict)
    return out


def test_observed_reference_keeps_the_level_where_the_direct_validation_flags_it():
    """20 seeds of the same process: direct NOT VALID in (nearly) all, because of the sensor;
    declared observed NOT VALID in at most 3 of 20 (P(X >= 4) = 0.016 at α = 0.05)."""
    verdicts = _verdicts(range(20))
    direct = verdicts["direct"].count("not valid")
    observed = verdicts["observed"].count("not valid")
    assert direct >= 18, verdicts["direct"]
    assert observed <= 3 and observed < direct, verdicts["observed"]


def test_a_real_reaction_delay_in_the_candidate_is_still_found():
    """The candidate reacts after 1.0 s, the recorded process after 0.5 s: declared observed,
    NOT VALID in at least 6 of 10 seeds (37 of 40 in the first measurement)."""
    verdicts = _verdicts(range(100, 110), reaction=10)
    assert verdicts["observed"].count("not valid") >= 6, verdicts["observed"]


def test_python_api_with_a_sensor_declared_inline_needs_no_inputs_sensor():
    rng = np.random.default_rng(9)
    reference, candidate = universe.recording(rng, 20, 50), universe.truth(rng, 20, 50)
    spec = universe.validation(0, sensor=universe.SENSOR)
    result = validate(spec, Inputs(reference, {"sim": candidate}, ()))
    assert result.observation is not None and result.observation.sensor == universe.SENSOR
    assert result.observation.cropped == 3


def _files(folder: Path, sensor: object) -> Path:
    rng = np.random.default_rng(5)
    universe.recording(rng, RUNS, STEPS).write(folder / "recorded.parquet")
    universe.truth(rng, RUNS, STEPS).write(folder / "sim.parquet")
    document = {
        "name": "observed reference",
        "test_case": {"conditions": "16 <= u <= 24", "tolerance": {"v": 0.25}},
        "reference": {"path": "recorded.parquet", "observed": {"sensor": sensor}},
        "candidates": {"sim": {"runs": {"path": "sim.parquet"}}},
        "features": ["u", "v"], "inputs": ["u"],
        "conditions": {"u": {"unit": "m/s", "edges": [16, 20, 24]}},
        "comparison": {"bins": 3, "permutations": 99, "seed": 1},
    }
    path = folder / "validation.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def estimated(tmp_path_factory) -> Path:
    """A validation with a sensor model estimated from 20 GT/SD pairs (30 draws), run."""
    folder = tmp_path_factory.mktemp("observed")
    gt, sd = universe.calibration_pairs(np.random.default_rng(6), 20, STEPS)
    estimate_sensor(gt, sd, bootstrap=30, seed=7).write(folder / "sensor.json")
    assert run(["-q", "validate", str(_files(folder, "sensor.json")), "--out",
                str(folder / "out")]) in (0, 3)
    return folder / "out"


def test_verdict_says_what_was_compared_the_sensor_and_the_sensor_alone(estimated):
    document = json.loads((estimated / "verdict.json").read_text())
    observation = document["observation"]
    assert (observation["reference"], observation["route"]) == ("observed", "observation model")
    assert observation["cropped_samples"] == 3  # the estimated delay 0.3 s at 0.1 s
    sensor = observation["sensor"]
    assert (sensor["kind"], sensor["draws"], sensor["source"]) == ("estimated", 30,
                                                                   "sensor.json")
    v = sensor["signals"]["v"]
    for key, true in (("offset", 0.3), ("delay", 0.3), ("noise_sd", 0.25), ("dropout", 0.05)):
        low, high = v["interval_95"][key]
        assert low <= v[key] <= high and abs(v[key] - true) < 0.05, (key, v)
    cells = observation["sensor_alone"]["sim"]
    assert [c["cell"] for c in cells] == document["candidates"]["sim"]["test_case_cells"]
    for cell in cells:  # the sensor alone is far beyond the tolerance: the direct bias
        (deviation,) = cell["deviation"]
        assert deviation["feature"] == "v" and deviation["estimate"] > 4 * 0.25
        assert cell["design"] == "pairs by run"
    assert document["provenance"]["options"]["reference"]["observed"] == {
        "sensor": "sensor.json"}
    html = (estimated / "report.html").read_text()
    for needle in ('id="observation"', 'id="sensor-model"', 'id="sensor-alone"',
                   "observation model", "estimated"):
        assert needle in html


def test_a_file_without_the_key_records_nothing_new(tmp_path):
    path = _files(tmp_path, "unused.json")
    document = yaml.safe_load(path.read_text())
    del document["reference"]["observed"]
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    assert run(["-q", "validate", str(path), "--out", str(tmp_path / "out")]) == 1
    verdict = json.loads((tmp_path / "out" / "verdict.json").read_text())
    assert "observation" not in verdict
    assert verdict["provenance"]["options"]["reference"] == {"path": "recorded.parquet",
                                                             "options": {}}
    assert 'id="observation"' not in (tmp_path / "out" / "report.html").read_text()


BAD = [
    (3, "reference.observed.sensor: a sensor model file (path) or"),
    ({"v": {"gain": 1}}, "reference.observed.sensor: declared sensor: signal 'v' has unknown "
                         "sensor field(s) ['gain']"),
    ({"v": {"dropout": 1.5}}, "reference.observed.sensor: sensor dropout must be in [0, 1)"),
    ({"v": {"noise_sd": -1}}, "reference.observed.sensor: sensor delay and noise_sd must be"),
    ({"w": {"noise_sd": 1}}, "reference.observed.sensor: "),
    ({"v": {"delay": 100}}, "too few for the sensor delay"),
    ("missing.json", "reference.observed.sensor: "),
    ("broken.json", "not JSON"),
]


@pytest.mark.parametrize(("sensor", "needle"), BAD, ids=[str(b[0]) for b in BAD])
def test_bad_declaration_is_one_line_exit_2(tmp_path, capsys, sensor, needle):
    (tmp_path / "broken.json").write_text("{")
    path = _files(tmp_path, sensor)
    assert run(["validate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert needle in err and "reference.observed" in err
    assert not (tmp_path / "out").exists()


def test_a_misspelt_or_misplaced_key_is_named(tmp_path, capsys):
    path = _files(tmp_path, "sensor.json")
    document = yaml.safe_load(path.read_text())
    document["reference"]["observed"] = {"sensr": "sensor.json"}
    document["candidates"]["sim"]["runs"]["observed"] = {"sensor": "sensor.json"}
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    assert run(["validate", str(path), "--out", str(tmp_path / "out")]) == 2
    assert "reference.observed" in capsys.readouterr().err
