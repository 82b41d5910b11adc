"""Notebook display and result tables: ``_repr_html_`` (a table and the figure, drawn in headless
Chromium) and ``to_pandas`` of comparisons and distance matrices, against the results' own
fields."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from browser import headless
from helpers import ar_set
from simcred.compare import compare, matrix
from simcred.traces import TraceSet

PAGE = """<!doctype html><html><head><meta charset="utf-8"></head><body>{body}
<script>window.addEventListener("load", () => {{
  const images = [...document.images];
  const ok = images.filter(i => i.complete && i.naturalWidth > 100).length;
  document.body.dataset.imagesLoaded = ok + "/" + images.length;
}});</script></body></html>"""


@pytest.fixture(scope="module")
def differing():
    rng = np.random.default_rng(4)
    a = ar_set(rng, runs=60, phi=0.7, source="model")
    b = ar_set(rng, runs=60, phi=-0.7, source="reality")
    return compare(a, b, features=["x", "y"], bins=4, test="permutation", permutations=99,
                   seed=1)


def test_states_frame_lists_every_start_state_with_its_test(differing):
    frame = differing.to_pandas()
    assert len(frame) == len(differing.states) + len(differing.untestable)
    by_state = {tuple(int(r[f"{f}.bin"]) for f in ("x", "y")): r for _, r in frame.iterrows()}
    for s in differing.states:
        row = by_state[s.state]
        assert row["status"] == ("rejected" if s.result.rejected else "kept")
        assert (row["m"], row["n"]) == (s.result.m, s.result.n)
        assert row["pvalue"] == s.result.pvalue and row["statistic"] == s.result.statistic
        for j, f in enumerate(("x", "y")):  # the bin's value range from the state space
            edges = differing.space.edges[j]
            low = -math.inf if s.state[j] == 0 else edges[s.state[j] - 1]
            high = math.inf if s.state[j] == len(edges) else edges[s.state[j]]
            assert (row[f"{f}.low"], row[f"{f}.high"]) == (low, high)
    for u in differing.untestable:
        assert by_state[u.state]["status"] == "untestable"
        assert math.isnan(by_state[u.state]["pvalue"])
    rejected = (frame["status"] == "rejected").sum()
    assert rejected / differing.n_states == differing.distance > 0


def test_matrix_frame_is_the_matrix():
    rng = np.random.default_rng(5)
    sets = [ar_set(rng, runs=40, phi=phi, source=f"s{i}") for i, phi in enumerate((0.7, -0.7))]
    result = matrix(sets, features=["x", "y"], bins=3, test="permutation", permutations=49,
                    seed=2)
    frame = result.to_pandas()
    assert list(frame.index) == list(frame.columns) == list(result.names)
    assert np.array_equal(frame.to_numpy(), result.distances, equal_nan=True)
    html = result._repr_html_()
    assert "Distance matrix" in html and html.count("<img") == 1


def test_traceset_html_lists_runs_units_and_draws_a_figure():
    ts = TraceSet.from_runs([{"t": [0, 1, 2], "v": [1, 2, 3]}, {"t": [0, 0.5], "v": [0, 1]}],
                            run_ids=["<b>", "a"], metadata={"units": {"v": "m/s"}})
    html = ts._repr_html_()
    assert "v [m/s]" in html
    assert "&lt;b&gt;" in html and "<b>" not in html  # run ids are text, escaped
    assert re.search(r"<td>&lt;b&gt;</td><td>3</td><td>0</td><td>2</td>", html)
    assert html.count('src="data:image/png;base64,') == 1


@pytest.mark.slow
def test_comparison_shows_a_table_and_the_state_map_in_chromium(chromium, differing, tmp_path):
    html = differing._repr_html_()
    assert f"{100 * differing.distance:.2f} %" in html
    page = tmp_path / "cell.html"
    page.write_text(PAGE.format(body=html), encoding="utf-8")
    dumped = headless(chromium, tmp_path / "profile", "--dump-dom",
                      "--virtual-time-budget=5000", page.resolve().as_uri())
    dom = dumped.stdout
    assert "<table>" in dom and "rejected states" in dom
    assert 'alt="state map"' in dom
    assert 'data-images-loaded="1/1"' in dom, dumped.stderr[-500:]


def test_validation_html_shows_the_verdict_candidates_and_ranking(tmp_path):
    from simcred.validate import read_inputs, read_validation, validate
    from validate.conftest import write_universe

    spec, base = read_validation(write_universe(tmp_path, runs=40, steps=100))
    result = validate(spec, read_inputs(spec, base))
    html = result._repr_html_()
    assert f"<h4>Validation: {result.verdict}</h4>" in html
    for name, verdict in result.candidates.items():
        assert f"<td>{name}</td><td>{verdict.verdict}</td>" in html
    assert any(r.score is not None for r in result.ranking)  # so the ranking is drawn
    assert html.count('src="data:image/png;base64,') == 1
    assert "&lt;= v &lt;= 25" in html  # the summary is text, escaped
    cells = result.to_pandas()  # the cells behind the verdict, against the domains' records
    expected = [(name, c.cell, c.status.value, c.reference_samples, c.candidate_samples)
                for name, domain in result.domains.items() for c in domain.cells]
    assert list(zip(cells["candidate"], cells["cell"], cells["status"],
                    cells["reference_samples"], cells["candidate_samples"],
                    strict=True)) == expected
    judged = cells.dropna(subset=["x.estimate"])
    for _, row in judged.iterrows():
        bound = result.domains[row["candidate"]].cells[row["cell"]].bounds[0]
        assert (row["x.estimate"], row["x.upper"]) == (bound.estimate, bound.upper)
        assert row["v.low"] <= row["v.high"]
