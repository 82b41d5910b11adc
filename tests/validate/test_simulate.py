"""A candidate made by a simulator command: SUMO replays of real OpenACC leaders, run by
`simcred validate` itself, give the same runs as `simcred simulate sumo-following` alone."""

from __future__ import annotations

import json

import pytest
import yaml

from simcred.cli import run
from simcred.io.openacc import HUMAN, read_openacc
from simcred.traces import TraceSet, take


@pytest.mark.slow
def test_simulator_command_candidate(tmp_path):
    human = read_openacc(follower=HUMAN)
    take(human, list(range(0, human.n_runs, 20))).write(tmp_path / "human.parquet")
    command = ["simulate", "sumo-following", "{base}/human.parquet", "--models", "IDM",
               "--out", "{out}"]
    document = {
        "test_case": {"conditions": "10 <= v_leader <= 20", "tolerance": {"v": 0.1}},
        "reference": {"path": "human.parquet"},
        "candidates": {"idm": {"simulate": {"command": command, "output": "IDM.parquet"}}},
        "features": ["gap", "v", "v_leader"], "inputs": ["v_leader"],
        "conditions": {"v_leader": {"unit": "m/s", "edges": [10, 15, 20]}},
        "comparison": {"bins": 3, "permutations": 99, "bootstrap": 100, "resample": 0.5},
        "min_data": {"runs": 5, "samples": 100}, "segments": {"min_length": 25},
    }
    path = tmp_path / "validation.yaml"
    path.write_text(yaml.safe_dump(document))
    code = run(["-q", "validate", str(path), "--out", str(tmp_path / "out"), "--no-report"])
    assert code in (0, 1, 3)
    made = TraceSet.read(tmp_path / "out" / "runs" / "idm" / "IDM.parquet")
    assert run(["-q", "simulate", "sumo-following", str(tmp_path / "human.parquet"), "--models",
                "IDM", "--out", str(tmp_path / "alone")]) == 0
    assert made.equals(TraceSet.read(tmp_path / "alone" / "IDM.parquet"))
    verdict = json.loads((tmp_path / "out" / "verdict.json").read_text())
    assert verdict["provenance"]["inputs"]["candidates"]["idm"]["digest"] == made.digest()
    designs = {c["design"] for c in verdict["domains"]["idm"]["cells"] if c["design"]}
    assert designs == {"pairs by run"}  # a replay is paired with the runs it replays
