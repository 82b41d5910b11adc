"""scripts/observed_realdata.py (issue 23, real data) runs on a tiny slice and writes its JSON."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "observed_realdata.py"


def _script():
    spec = importlib.util.spec_from_file_location("_observed_realdata", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_observed_realdata_runs_on_a_tiny_slice(tmp_path):
    out = tmp_path / "real.json"
    _script().main(["--episodes", "12", "--permutations", "19", "--bootstrap", "100",
                    "--out", str(out)])
    result = json.loads(out.read_text())
    assert set(result) == {"protocol", "direct", "observed", "sensor_effect", "seconds"}
    protocol = result["protocol"]
    assert protocol["data"]["episodes"] == 12
    assert protocol["observed"] == "b"
    assert protocol["options"]["permutations"] == 19
    assert set(protocol["sensor"]["signals"]) == {"gap", "v"}
    assert protocol["sensor"]["signals"]["v"]["noise_sd"] == 0.05
    for key in ("direct", "observed", "sensor_effect"):
        part = result[key]
        assert isinstance(part["rejected"], bool)
        assert 0.0 < part["pvalue"] <= 1.0
        assert set(part["deviation"]) == {"gap", "v"}
        for dev in part["deviation"].values():
            assert dev["low"] <= dev["high"]
    assert result["observed"]["cropped"] == 0  # no delay declared: nothing cropped
