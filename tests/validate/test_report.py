"""The validation report: text checks (verdict first, domain map, escaping, self-contained) and a
real headless Chromium that finds the verdict, the domain map and every image decoded."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib.image as mpimg
import pytest

from browser import headless
from simcred.cli import run

from .conftest import write_universe


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("validate")
    path = write_universe(folder, name="<b>evil</b> & name",
                          monitor=[{"path": "twin.parquet"}])
    assert run(["-q", "validate", str(path), "--out", str(folder / "out")]) == 1
    return folder / "out" / "report.html"


def test_report_text(report):
    html = report.read_text()
    body = html[html.index("<main>"):]
    assert body.index('id="verdict"') < body.index('id="candidate-sim"')
    assert "NOT VALID" in body[:body.index('id="candidate-sim"')]
    assert 'id="domain-map-sim"' in html
    assert "&lt;b&gt;evil&lt;/b&gt; &amp; name" in html and "<b>evil</b>" not in html
    assert not re.search(r'(src|href)="(?!data:)', html)  # nothing outside the file
    images = re.findall(r'<img src="data:image/png;base64,', html)
    assert len(images) == 1 + 1 + 5  # ranking, domain map, one state map per compared cell
    assert 'id="configuration"' in html and 'id="provenance"' in html
    assert "sim on monitor[0]" in html
    rules_out = " ".join(body[body.index('id="what-it-rules-out"'):
                              body.index('id="ranking"')].split())
    assert "tolerance" in rules_out and "≤ 1.0" in rules_out  # the test case's tolerance
    assert "upper 95 % bound" in rules_out and "at most 0.05 per candidate" in rules_out
    assert "permutation floor" in rules_out and "over the 3 cells" in rules_out


def test_cell_table_shows_each_upper_bound_s_floor(report):
    """Every judged feature's decision bounds carry the floor of the verdict's JSON."""
    import json
    document = json.loads((report.parent / "verdict.json").read_text())
    html = report.read_text()
    floors = [d["upper_floor"] for c in document["domains"]["sim"]["cells"]
              for d in c["deviation"] if d["upper_floor"] is not None]
    assert floors
    for floor in floors:
        assert f"(floor {floor:.3g})" in html


def test_verdict_states_its_error_rates(report):
    import json
    document = json.loads((report.parent / "verdict.json").read_text())
    assert "z3-solver" in document["provenance"]["versions"]  # its proofs are in the verdict
    rates = document["error_rates"]
    assert rates["alpha"] == 0.05 and rates["test_case_cells"] == 3
    assert "upper 0.95 bound" in rates["false_valid"]
    assert "lower 0.9833 bound" in rates["false_not_valid"]  # Bonferroni: 1 - 0.05 / 3
    assert "rejecting the same law at 0.01667" in rates["false_not_valid"]


@pytest.mark.slow
def test_report_renders_in_chromium(chromium, report, tmp_path):
    url = report.resolve().as_uri()
    shot = tmp_path / "shot.png"
    done = headless(chromium, tmp_path / "p1", f"--screenshot={shot}", "--window-size=1280,1400",
                     url)
    assert shot.is_file(), f"no screenshot (exit {done.returncode}): {done.stderr[-800:]}"
    pixels = mpimg.imread(shot)
    assert pixels.shape[:2] == (1400, 1280) and pixels[..., :3].std() > 0.01
    dom = headless(chromium, tmp_path / "p2", "--dump-dom", "--virtual-time-budget=5000",
                    url).stdout
    assert 'id="verdict"' in dom and "NOT VALID" in dom
    assert 'id="domain-map-sim"' in dom
    match = re.search(r'<body[^>]*\bdata-images-loaded="(\d+)/(\d+)"', dom)
    assert match, "the page's load handler did not run"
    loaded, total = map(int, match.groups())
    assert loaded == total == 7


def test_cells_with_a_constant_feature_are_named_not_drawn(tmp_path):
    from simcred.report.validate import write_validation_report
    from simcred.traces import TraceSet
    from simcred.validate import read_inputs, read_validation, validate
    from simcred.validate.verdict import verdict_document

    path = write_universe(tmp_path, features=["v", "x"])
    spec, base = read_validation(path)
    inputs = read_inputs(spec, base)
    flat = {}
    for name, traces in (("reference", inputs.reference), *inputs.candidates.items()):
        values = traces.values.copy()
        values[:, traces.signals.index("v")] = 7.0  # every row in the first cell, v constant
        flat[name] = TraceSet(traces.signals, traces.time, values, traces.offsets,
                              traces.run_ids, source=traces.source)
    inputs = type(inputs)(flat["reference"], {"sim": flat["sim"]}, ())
    result = validate(spec, inputs)
    out = tmp_path / "out"
    out.mkdir()
    html = write_validation_report(result, verdict_document(result, inputs), out).read_text()
    assert "No state map where a drawn feature is constant" in html
    assert "5 ≤ v &lt; 10" in html
