"""`simcred report DIR`: a self-contained, deterministic HTML page, checked as text and in Chromium.

The unit tests build a synthetic `simcred paper all` directory (small matplotlib PNGs, claims that
pass and fail, paper 003's findings.json) and a partial one. The browser test renders the page in
headless Chromium: a screenshot that is not blank, and the dumped DOM after the `load` event, in
which the page's own script has counted the images that decoded (`data-images-loaded`).
"""

from __future__ import annotations

import base64
import json
import re
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import pytest  # noqa: E402

from browser import headless  # noqa: E402
from simcred.cli import run  # noqa: E402
from simcred.errors import SimcredError  # noqa: E402
from simcred.paper.all import AllOptions, _write_combined  # noqa: E402
from simcred.report.html import MAX_VIOLATIONS, render_report, write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SECTIONS = ("paper-000", "paper-002", "paper-003", "provenance")
FIGURES = {
    "000": ["fig5_inputs.png", "fig6_xy.png", "fig7_xy_heading.png", "table3_bound.png",
            "table3_permutation.png", "extra_histogram.png"],
    "002": ["figures/fig3_fit.png", "figures/fig4_errors.png",
            "figures/fig4_errors_scenario_based.png", "figures/fig5_sd_velocity.png",
            "figures/fig6_traces.png", "figures/fig7_velocity_risk.png",
            "variations/figures/fig8_variations.png"],
    "003": [],
}
EVIL = "<script>alert('pwned')</script> & \"quotes\""
VIOLATIONS = 27
TIMEOUT = 60


def _png(path: Path, k: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(3.2, 2.0))
    ax.plot([0, 1, 2, 3], [k % 3, k, 2 * k % 5, 1], color=f"C{k % 10}", lw=2)
    ax.set_title(path.stem, fontsize=8)
    fig.savefig(path, dpi=60, metadata={"Software": "test", "Creation Time": None})
    plt.close(fig)


def _claims(paper: str) -> list[dict]:
    claims = [
        {"id": f"{paper}.holds", "claim": f"paper {paper}: something that holds", "value": 0.5,
         "bound": 0.9, "passed": True, "note": "value below bound"},
        {"id": f"{paper}.fails", "claim": f"paper {paper}: something that fails", "value": 3.25,
         "bound": 2.0, "passed": False, "note": ""},
    ]
    if paper == "000":
        claims.append({"id": "000.escaped", "claim": EVIL, "value": None, "bound": None,
                       "passed": True, "note": EVIL})
    return claims


PROVENANCE = {
    "000": {"simplecar_sweep": {"experiment": "simplecar-sweep", "runs": 40, "seed": 0,
                                "lambdas": [round(0.81 + 0.01 * i, 2) for i in range(40)]},
            "tjunction": {"experiment": "tjunction", "runs": 40, "sets_per_category": 3,
                          "seed": 0, "features": ["ego.x", "ego.y"]}},
    "002": {"cutin": {"experiment": "cutin", "seed": 0, "sensor": {"offset": 1.4,
                                                                   "delay": {"mean": 0.2}}},
            "variations": {"n": 300, "seed": 1}},
    "003": {"contracts": {"library": "examples/library.yaml", "test_case": "cut_in"}},
}
TITLES = {"000": "Neurohr et al. (synthetic)", "002": "Wagner, Groh et al. (synthetic)",
          "003": "Braun et al. (synthetic)"}


def _findings() -> dict:
    violation = {"contract": "camera_v1", "kind": "assumption", "clause": "rain <= 2",
                 "run": "run_3", "t_start": 1.5, "t_end": 2.25, "margin": -0.125}
    return {
        "library": "examples/library.yaml",
        "configuration": {"test_case": "cut_in", "setup": {"sensor": "camera_v1",
                                                           "vehicle": "ks_model"},
                          "cost": 3.5, "verdict": "holds", "checked_setups": 4,
                          "explanation": "the cheapest of 2 valid setups"},
        "quotient": {"removed": "camera_v1", "test_case": "cut_in",
                     "configurable_without": False, "without_reason": "no setup refines it",
                     "given": {"vehicle": "ks_model"},
                     "requirement": "assume: rain <= 2\nguarantee: |d_err| <= 0.5 & x < y",
                     "accepts": {"camera_v1": True, "lidar_v2": False}},
        "monitors": [
            {"name": "cut-in runs", "runs": 5, "samples": 500, "passed": False,
             "violations": [{**violation, "run": f"run_{i}"} for i in range(VIOLATIONS)]},
            {"name": "clean runs", "runs": 3, "samples": 300, "passed": True, "violations": []},
        ],
    }


def make_paper_dir(root: Path, papers=("000", "002", "003")) -> Path:
    """A synthetic `simcred paper all` output with the given paper folders."""
    root.mkdir(parents=True, exist_ok=True)
    k = 0
    entries = {}
    for paper in papers:
        folder = root / f"paper{paper}"
        for name in FIGURES[paper]:
            _png(folder / name, k)
            k += 1
        entries[paper] = {"title": TITLES[paper], "provenance": PROVENANCE[paper],
                          "claims": _claims(paper)}
        (folder / "claims.json").parent.mkdir(parents=True, exist_ok=True)
        (folder / "claims.json").write_text(json.dumps(
            {"schema_version": 1, "kind": "claims", "simcred_version": "0.1.0", **entries[paper]}))
        if paper == "003":
            (folder / "findings.json").write_text(json.dumps(_findings()))
    document = {"schema_version": 1, "kind": "claims_all", "simcred_version": "0.1.0",
                "papers": entries,
                "run": {"command": "simcred paper all --out DIR --runs 40",
                        "options": {"runs": 40, "seed": 0, "variations": 300},
                        "versions": {"simcred": "0.1.0", "numpy": "2.0.0", "python": "3.11"},
                        "inputs": {"library.yaml": "ab" * 32}}}
    (root / "claims.json").write_text(json.dumps(document, indent=1))
    return root


@pytest.fixture(scope="module")
def full_dir(tmp_path_factory) -> Path:
    return make_paper_dir(tmp_path_factory.mktemp("report") / "all")


@pytest.fixture(scope="module")
def full_report(full_dir) -> tuple[Path, str]:
    path = write_report(full_dir)
    return path, path.read_text(encoding="utf-8")


def _section(html: str, anchor: str) -> str:
    start = html.index(f'<section id="{anchor}">')
    return html[start:html.index("</section>", start)]


def _claim_row(html: str, paper: str, claim_id: str) -> str:
    match = re.search(rf'<tr id="claim-{paper}-{re.escape(claim_id)}"[^>]*>.*?</tr>', html, re.S)
    assert match, f"no row for claim {claim_id}"
    return match.group(0)


def test_every_section_claim_and_status_is_on_the_page(full_report):
    path, html = full_report
    assert path.name == "index.html"
    for anchor in SECTIONS:
        assert f'<section id="{anchor}">' in html
        assert f'href="#{anchor}"' in html  # table of contents
    for paper in ("000", "002", "003"):
        section = _section(html, f"paper-{paper}")
        for claim in _claims(paper):
            row = _claim_row(section, paper, claim["id"])
            status = "pass" if claim["passed"] else "fail"
            assert f'<span class="badge {status}">{status}</span>' in row
            assert f"<code>{claim['id']}</code>" in row
    # 4 pass, 3 fail
    assert "4 of 7 claims hold" in html
    assert 'href="#claim-002-002.fails"' in html  # failing claims are linked from the header


def test_every_png_is_embedded_and_nothing_is_fetched(full_dir, full_report):
    _, html = full_report
    pngs = sorted(full_dir.rglob("*.png"))
    assert len(pngs) == sum(len(v) for v in FIGURES.values())
    assert html.count("data:image/png;base64,") == len(pngs)
    embedded = {base64.b64decode(uri) for uri in
                re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)}
    assert embedded == {p.read_bytes() for p in pngs}
    assert "http://" not in html and "https://" not in html
    for attribute, value in re.findall(r'\b(src|href)\s*=\s*"([^"]*)"', html):
        assert value.startswith("data:image/png;base64," if attribute == "src" else "#"), value
    assert "<link" not in html and "@import" not in html and "url(" not in html


def test_figures_in_the_papers_order_then_extras(full_report):
    _, html = full_report
    section = _section(html, "paper-000")
    order = [section.index(f"paper000/{name}</code>") for name in FIGURES["000"]]
    assert order == sorted(order)  # extra_histogram.png (unknown) comes last
    assert "Fig. 5: the input functions" in section
    assert "Table 3 with a permutation test" in section
    reprocessing = _section(html, "paper-002")
    assert "Fig. 3: the scenario description fitted to GT" in reprocessing
    assert "Fig. 8: the simulations of the variations" in reprocessing


def test_provenance_is_flattened_and_run_record_shown(full_report):
    _, html = full_report
    reprocessing = _section(html, "paper-002")
    assert "<code>cutin.sensor.delay.mean</code>" in reprocessing
    assert "simplecar_sweep: experiment = simplecar-sweep, runs = 40, seed = 0" in html
    assert "(40 values)" in html  # long lists abbreviated, full value in the title
    provenance = _section(html, "provenance")
    assert "simcred paper all --out DIR --runs 40" in provenance
    assert "ab" * 32 in provenance
    assert "<code>numpy</code>" in provenance
    assert "<td>paper 002</td><td><code>variations.seed</code></td>" in provenance  # seeds
    # are collected from the run options and every paper's provenance


def test_paper_003_findings(full_report):
    _, html = full_report
    section = _section(html, "paper-003")
    assert "<code>camera_v1</code>" in section and "ks_model" in section
    assert "<pre>assume: rain &lt;= 2\nguarantee: |d_err| &lt;= 0.5 &amp; x &lt; y</pre>" in section
    assert "no: no setup refines it" in section
    assert "vehicle = <code>ks_model</code>" in section
    assert '<span class="badge pass">yes</span>' in section  # camera_v1 accepted
    assert '<span class="badge fail">no</span>' in section  # lidar_v2 refused
    assert f"{VIOLATIONS} violations (the first {MAX_VIOLATIONS} shown)" in section
    assert section.count("<td><code>camera_v1</code></td><td>assumption</td>") == MAX_VIOLATIONS
    assert '<span class="badge fail">violated</span>' in section
    assert '<span class="badge pass">passed</span>' in section


def test_claim_text_is_escaped(full_report):
    _, html = full_report
    assert "<script>alert" not in html
    assert "&lt;script&gt;alert(&#39;pwned&#39;)&lt;/script&gt; &amp; &#34;quotes&#34;" in html
    assert html.count("<script") == 1  # the page's own image counter only


def test_same_directory_gives_byte_identical_html(full_dir, full_report, tmp_path):
    path, _ = full_report
    again = write_report(full_dir, out=tmp_path / "again.html")
    assert again.read_bytes() == path.read_bytes()
    assert render_report(full_dir).encode() == path.read_bytes()


def test_partial_directory_names_what_is_missing(tmp_path):
    root = make_paper_dir(tmp_path / "partial", papers=("000", "002"))
    (root / "paper002" / "figures" / "fig6_traces.png").unlink()
    html = write_report(root).read_text(encoding="utf-8")
    for anchor in SECTIONS:
        assert f'<section id="{anchor}">' in html
    assert html.count("data:image/png;base64,") == len(list(root.rglob("*.png")))
    validity_contracts = _section(html, "paper-003")
    assert "not run: claims.json has no entry for paper 003" in validity_contracts
    assert "<code>paper003/</code> is missing" in validity_contracts
    assert "Missing: <code>paper002/figures/fig6_traces.png</code>" in html
    assert "4 of 5 claims hold" not in html and "3 of 5 claims hold" in html


def test_damaged_parts_do_not_stop_the_report(tmp_path):
    root = make_paper_dir(tmp_path / "damaged")
    (root / "paper003" / "findings.json").write_text("{ not json")
    (root / "paper000" / "fig6_xy.png").write_bytes(b"\x89PNG\r\n")  # cut off while written
    document = json.loads((root / "claims.json").read_text())
    del document["papers"]["002"], document["run"]  # falls back to paper002/claims.json
    document["papers"]["000"]["claims"].append({"id": "000.odd", "passed": "maybe"})
    (root / "claims.json").write_text(json.dumps(document))
    html = write_report(root).read_text(encoding="utf-8")
    assert "paper003/findings.json is not valid JSON (line 1, column 3)" in html
    assert "<code>paper000/fig6_xy.png</code>: not a PNG file" in html
    assert "shown from paper002/claims.json" in html
    assert '<span class="badge unknown">unknown</span>' in _claim_row(html, "000", "000.odd")
    assert "claims.json has no run record" in html


def _shows_the_three_papers(html: str) -> None:
    for paper in ("000", "002", "003"):
        section = _section(html, f"paper-{paper}")
        assert f"<h2>Paper {paper}: " in section
        assert "no entry for paper" not in section  # read from the top-level claims.json
        for claim in _claims(paper):
            _claim_row(section, paper, claim["id"])
    assert "4 of 7 claims hold" in html


def test_claims_json_of_paper_all_is_read(tmp_path):
    """The top-level claims.json as `simcred paper all` writes it (key "papers")."""
    root = make_paper_dir(tmp_path / "all")
    _write_combined(root, AllOptions(runs=40), {"library.yaml": "ab" * 32})
    document = json.loads((root / "claims.json").read_text())
    assert list(document["papers"]) == ["000", "002", "003"] and "seeds" not in document
    _shows_the_three_papers(render_report(root))


def test_old_claims_json_with_seeds_key_still_shows_the_papers(tmp_path):
    """A claims.json written before the papers were keyed "papers" keys them "seeds"."""
    root = make_paper_dir(tmp_path / "old")
    document = json.loads((root / "claims.json").read_text())
    document = {("seeds" if k == "papers" else k): v for k, v in document.items()}
    (root / "claims.json").write_text(json.dumps(document))
    html = render_report(root)
    _shows_the_three_papers(html)
    assert "<td>paper 002</td><td><code>variations.seed</code></td>" in html


def test_bad_directory_is_one_line_error(tmp_path, capsys):
    with pytest.raises(SimcredError, match=re.escape(str(tmp_path / "nope"))):
        write_report(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(SimcredError, match=re.escape(str(tmp_path / "empty" / "claims.json"))):
        write_report(tmp_path / "empty")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "claims.json").write_text('{"kind": "claims"}')
    with pytest.raises(SimcredError, match="expected 'claims_all'"):
        write_report(tmp_path / "bad")
    capsys.readouterr()
    assert run(["report", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "claims.json" in err
    assert "Traceback" not in err


def test_cli_prints_the_written_path(full_dir, tmp_path, capsys):
    out = tmp_path / "sub" / "report.html"
    assert run(["report", str(full_dir), "--out", str(out)]) == 0
    assert capsys.readouterr().out.strip() == str(out)
    assert out.read_bytes() == (full_dir / "index.html").read_bytes()
    assert run(["--quiet", "report", str(full_dir), "--out", str(out)]) == 2  # exists
    assert "--overwrite" in capsys.readouterr().err
    assert run(["--quiet", "report", str(full_dir), "--out", str(out), "--overwrite"]) == 0
    assert capsys.readouterr().out == ""


# --- the real browser ---------------------------------------------------------------------------

@pytest.mark.slow
def test_report_renders_in_chromium(chromium, full_report, tmp_path):
    path, _ = full_report
    url = path.resolve().as_uri()
    screenshot = tmp_path / "report.png"
    shot = headless(chromium, tmp_path / "profile-shot", f"--screenshot={screenshot}",
                     "--window-size=1280,2000", url)
    assert screenshot.is_file(), f"no screenshot (exit {shot.returncode}): {shot.stderr[-800:]}"
    assert screenshot.stat().st_size > 10_000
    pixels = mpimg.imread(screenshot)
    assert pixels.shape[:2] == (2000, 1280)
    assert pixels[..., :3].std() > 0.01  # not a blank page

    dumped = headless(chromium, tmp_path / "profile-dom", "--dump-dom",
                       "--virtual-time-budget=5000", url)
    dom = dumped.stdout
    assert dom.strip(), f"empty DOM (exit {dumped.returncode}): {dumped.stderr[-800:]}"
    for anchor in SECTIONS:
        assert f'id="{anchor}"' in dom
    match = re.search(r'<body[^>]*\bdata-images-loaded="(\d+)/(\d+)"', dom)
    assert match, "the page's load handler did not run (no data-images-loaded on <body>)"
    loaded, total = map(int, match.groups())
    assert total == sum(len(v) for v in FIGURES.values())
    assert loaded == total > 0
