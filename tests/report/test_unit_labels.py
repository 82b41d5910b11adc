"""State maps show the units the trace sets declare on their axes."""

from __future__ import annotations

import numpy as np

from simcred.compare import compare
from simcred.report.figures import state_map, unit_labels
from simcred.traces import TraceSet


def _sets():
    rng = np.random.default_rng(0)
    runs = [{"t": np.arange(30) * 0.1, "gap": 20 + np.cumsum(rng.normal(size=30)),
             "v": 10 + np.cumsum(rng.normal(size=30))} for _ in range(16)]
    meta = {"units": {"gap": "m", "v": "m/s"}}
    return (TraceSet.from_runs(runs[:8], metadata=meta, source="a"),
            TraceSet.from_runs(runs[8:], metadata=meta, source="b"))


def test_axis_labels_carry_units(tmp_path):
    a, b = _sets()
    result = compare(a, b, features=["gap", "v"], bins=3, permutations=19, seed=0)
    assert unit_labels(result) == {"gap": "gap [m]", "v": "v [m/s]"}
    assert state_map(result, tmp_path / "map.png").stat().st_size > 5_000


def test_history_features_take_the_unit_of_their_signal():
    a, b = _sets()
    result = compare(a, b, features=["gap"], bins=3, permutations=19, seed=0, history=2)
    labels = unit_labels(result)
    assert labels and all(label.endswith("[m]") for label in labels.values())
    assert set(labels) == set(result.space.features)
