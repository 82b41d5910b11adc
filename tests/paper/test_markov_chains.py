"""Paper 000 reproduction: claim logic on known curves, and the whole command at a tiny size."""

import json

import numpy as np
import pytest

from simcred.compare.pairwise import DistanceMatrix
from simcred.paper.markov_chains import (
    FEATURE_SETS,
    KERNELS,
    TESTS,
    SweepConfig,
    SweepResult,
    sweep_claims,
    tjunction_claims,
)


def synthetic_sweep(xy_gauss, xy_laplace, xy_linear, heading):
    config = SweepConfig()
    curves = {"xy": {"gaussian": xy_gauss, "laplace": xy_laplace, "linear": xy_linear},
              "xy_heading": {k: heading for k in KERNELS}}
    distances = {f: {t: {k: list(map(float, curves[f][k])) for k in KERNELS} for t in TESTS}
                 for f in FEATURE_SETS}
    return SweepResult(config, distances)


def test_sweep_claims_pass_on_the_papers_shape():
    gap = np.abs(np.asarray(SweepConfig().lambdas) - 1)
    rng = np.random.default_rng(0)
    result = synthetic_sweep(gap, gap * 1.2 + 0.001, np.full(40, 0.001), rng.uniform(size=40))
    claims = {c.id.split(".")[2]: c for c in sweep_claims(result, "bound")}
    assert all(c.passed for c in claims.values()), claims
    assert claims["gaussian-ranks-lambda"].value == pytest.approx(1.0)


def test_sweep_claims_fail_when_the_shape_is_wrong():
    gap = np.abs(np.asarray(SweepConfig().lambdas) - 1)
    flat = np.random.default_rng(1).uniform(size=40)
    result = synthetic_sweep(flat, -gap, gap, gap)
    claims = {c.id.split(".")[2]: c for c in sweep_claims(result, "permutation")}
    assert not claims["gaussian-ranks-lambda"].passed
    assert not claims["laplace-ranks-lambda"].passed
    assert not claims["linear-fails"].passed
    assert not claims["heading-weakens-laplace"].passed


def test_tjunction_claims():
    d = np.full((9, 9), 0.08)
    for g in range(3):
        d[3 * g:3 * g + 3, 3 * g:3 * g + 3] = 0.01
    np.fill_diagonal(d, 0.0)
    table = DistanceMatrix(tuple("abcdefghi"), d, ())
    same, separate = tjunction_claims(table, "bound", 3)
    assert same.passed and separate.passed and separate.value == 0.08
    d[0, 1] = d[1, 0] = 0.09
    same, separate = tjunction_claims(DistanceMatrix(tuple("abcdefghi"), d, ()), "bound", 3)
    assert not same.passed and not separate.passed


@pytest.mark.slow
def test_paper_000_command_writes_every_output(tmp_path):
    from simcred.cli import run

    assert run(["--quiet", "paper", "000", "--out", str(tmp_path), "--runs", "30"]) == 0
    for name in ("fig5_inputs.png", "fig6_xy.png", "fig7_xy_heading.png",
                 "fig6_fig7_distances.csv", "table3_bound.png", "table3_permutation.csv",
                 "table3_bound.json", "claims.json"):
        assert (tmp_path / name).stat().st_size > 0, name
    doc = json.loads((tmp_path / "claims.json").read_text())
    ids = [c["id"] for c in doc["claims"]]
    assert len(ids) == len(set(ids)) == 2 * (6 + 2)
    assert all(set(c) >= {"id", "claim", "value", "bound", "passed"} for c in doc["claims"])
