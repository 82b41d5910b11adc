"""`simcred compare` leads with the chain verdict and the same-model baseline (issue 11)."""

from __future__ import annotations

import json

import numpy as np

from helpers import ar_set
from simcred.cli import run
from simcred.examples import lane_change_sets


def test_default_output_leads_with_chain_verdict_and_baseline(tmp_path, capsys):
    rng = np.random.default_rng(1)
    a, b = ar_set(rng, runs=40, phi=0.7), ar_set(rng, runs=40, phi=-0.7)
    pa, pb = a.write(tmp_path / "a"), b.write(tmp_path / "b.parquet")
    code = run(["compare", str(pa), str(pb), "-f", "x,y", "--bins", "5", "--permutations",
                "199", "--baseline", "3", "--seed", "2", "--out", str(tmp_path / "out")])
    assert code == 0
    lines = [line for line in capsys.readouterr().out.splitlines() if "│" in line]
    assert "chain verdict" in lines[0] and "DIFFERENT" in lines[0]
    assert any("same-model baseline" in line for line in lines[:4])
    doc = json.loads((tmp_path / "out" / "comparison.json").read_text())
    assert doc["options"]["test"] == "runs" and doc["options"]["multiplicity"] == "fwer"
    assert doc["chain"]["rejected"] and doc["chain"]["permutations"] == 199
    assert len(doc["baseline"]["distances"]) == 3
    assert doc["distance"] == sum(s["rejected"] for s in doc["states"]) / doc["n_states"]


def test_paper_tests_unchanged_and_without_chain(tmp_path, capsys):
    a, b = lane_change_sets(runs=40, steps=30, seed=2)
    pa, pb = a.write(tmp_path / "a"), b.write(tmp_path / "b")
    assert run(["compare", str(pa), str(pb), "-f", "x,y", "--bins", "4", "--test", "bound",
                "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert "chain" not in doc and "baseline" not in doc
    assert doc["options"]["multiplicity"] == "none"
