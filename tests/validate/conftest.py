"""A small synthetic universe on disk: reference, a candidate valid below 20 m/s, new runs.

The candidate's AR coefficient is 0.3 higher above 20 m/s: a response deviation of about 2.5-3.6
per second there, against the test case's tolerance 1.0 (0 below 20 m/s, where the bootstrap
upper bounds at this size are 0.4-0.8)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from simcred.validate.synthetic import universe

EDGES = [5, 10, 15, 20, 25, 30]


def write_universe(folder: Path, *, runs: int = 100, steps: int = 150, effect: float = 0.3,
                   seed: int = 1, **overrides) -> Path:
    universe(runs, steps, seed=seed).write(folder / "ref.parquet")
    universe(runs, steps, seed=seed + 1, effect=effect, v_switch=20,
             name="sim").write(folder / "sim.parquet")
    universe(runs, steps, seed=seed + 2, name="twin").write(folder / "twin.parquet")
    document = {
        "name": "synthetic",
        "test_case": {"conditions": "10 <= v <= 25", "tolerance": {"x": 1.0}},
        "reference": {"path": "ref.parquet"},
        "candidates": {"sim": {"runs": {"path": "sim.parquet"}, "cost": 1}},
        "features": ["x"],
        "conditions": {"v": {"unit": "m/s", "edges": EDGES}},
        "comparison": {"bins": 4, "permutations": 99, "seed": 7},
        "min_data": {"runs": 8, "samples": 200},
    }
    document.update(overrides)
    path = folder / "validation.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


@pytest.fixture
def validation_file(tmp_path) -> Path:
    return write_universe(tmp_path)
