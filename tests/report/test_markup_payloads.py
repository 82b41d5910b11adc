"""Markup payloads through every field of both HTML reports reach the page as text only.

The papers' report (``simcred report``, with the paper 002 section) gets a payload in every string
of its claims files (claim ids and texts, notes, provenance keys and values, run options, input
file names, monitors' run ids, clauses and signal names), in figure file names and in its folder
name; the validation report (``simcred validate``) gets them in the validation's name, the trace
files' names, run ids and the compared signal's name. The page is then parsed (html.parser, and in
headless Chromium after its own script ran): it must have exactly the scripts and handler
attributes of a report made from harmless inputs, and no reference outside itself (every ``src``
is a ``data:`` image, every ``href`` an anchor on the page).
"""

from __future__ import annotations

import dataclasses
import json
from html.parser import HTMLParser
from pathlib import Path

import pytest
import yaml

from browser import headless
from report.test_html import make_paper_dir
from simcred.cli import run
from simcred.validate.synthetic import universe

PAYLOADS = ("<script>alert(1)</script>", '" onerror="alert(1)', "javascript:alert(1)",
            "<img src=http://evil.example/x.png>", "' onmouseover='alert(1)",
            "<a href=https://evil.example>x</a>")
#: Attributes that make the browser fetch or navigate.
URL_ATTRIBUTES = {"src", "href", "action", "formaction", "srcset", "poster", "data", "background",
                  "xlink:href", "ping", "cite", "longdesc", "manifest"}
ACTIVE_TAGS = {"script", "iframe", "frame", "object", "embed", "link", "base", "form", "meta",
               "svg", "math", "template", "applet", "audio", "video", "source"}


class Page(HTMLParser):
    """The active parts of a page: tags that run or fetch, handler attributes, URLs, text."""

    def __init__(self, html: str) -> None:
        super().__init__(convert_charrefs=True)
        self.active: list[tuple[str, tuple]] = []  # (tag, attribute names) of active tags
        self.handlers: list[tuple[str, str, str]] = []  # (tag, attribute, value)
        self.urls: list[tuple[str, str, str]] = []
        self.scripts: list[str] = []
        self.text: list[str] = []
        self._in_script = False
        self.feed(html)
        self.close()

    def handle_starttag(self, tag, attrs):
        if tag in ACTIVE_TAGS:
            self.active.append((tag, tuple(sorted(k for k, _ in attrs))))
        self._in_script = tag == "script"
        for name, value in attrs:
            if name.startswith("on"):
                self.handlers.append((tag, name, value or ""))
            if name in URL_ATTRIBUTES:
                self.urls.append((tag, name, value or ""))

    def handle_endtag(self, tag):
        if tag == "script":
            self._in_script = False

    def handle_data(self, data):
        (self.scripts if self._in_script else self.text).append(data)


def check_page(html: str, baseline: str) -> Page:
    """``html`` runs and fetches nothing that the page made from harmless inputs does not."""
    page, own = Page(html), Page(baseline)
    assert sorted(page.active) == sorted(own.active)  # its metas, its own script: no more
    assert page.scripts == own.scripts
    assert sorted(page.handlers) == sorted(own.handlers)
    for tag, name, value in page.urls:
        allowed = value.startswith("data:image/png;base64,") if name == "src" else \
            name == "href" and value.startswith("#")
        assert allowed, (tag, name, value[:120])
    return page


def _shown(page: Page, payload: str) -> bool:
    return payload in "".join(page.text)


# --- the papers' report (simcred report), paper 002 and all others ------------------------------

#: Values the report needs to recognise a file (kept); every other string becomes a payload.
STRUCTURAL = {"kind"}


def _poison(value, counter: list[int], *, keys: bool):
    """Every string (and, with ``keys``, every mapping key of free-form data) a payload."""
    def payload(original: str) -> str:
        counter[0] += 1
        return f"{original}{PAYLOADS[counter[0] % len(PAYLOADS)]}"

    if isinstance(value, dict):
        poisoned = {}
        for k, v in value.items():
            free = keys and k not in ("papers", "claims", "run", "provenance", "configuration",
                                      "quotient", "monitors", "violations", "options",
                                      "versions", "inputs", "setup", "given", "accepts")
            new_key = payload(k) if free and k not in {"id", "claim", "value", "bound",
                                                       "passed", "note", "title"} else k
            poisoned[new_key] = v if k in STRUCTURAL else _poison(v, counter, keys=True)
        return poisoned
    if isinstance(value, list):
        return [_poison(v, counter, keys=keys) for v in value]
    return payload(value) if isinstance(value, str) else value


def _poisoned_paper_dir(root: Path) -> Path:
    folder = make_paper_dir(root / "all")
    counter = [0]
    for path in sorted(folder.rglob("*.json")):
        path.write_text(json.dumps(_poison(json.loads(path.read_text()), counter, keys=False)))
    png = next((folder / "paper002").rglob("*.png")).read_bytes()
    for payload in PAYLOADS:  # figure file names ("/" cannot be in a name)
        (folder / "paper002" / f"{payload.replace('/', '|')}.png").write_bytes(png)
    return folder.rename(root / f"all{PAYLOADS[0].replace('/', '|')}")


@pytest.fixture(scope="module")
def papers_reports(tmp_path_factory) -> tuple[str, str]:
    root = tmp_path_factory.mktemp("payloads")
    harmless = make_paper_dir(root / "harmless")
    assert run(["-q", "report", str(harmless), "--out", str(root / "harmless.html")]) == 0
    poisoned = _poisoned_paper_dir(root)
    assert run(["-q", "report", str(poisoned), "--out", str(root / "poisoned.html")]) == 0
    return ((root / "poisoned.html").read_text(encoding="utf-8"),
            (root / "harmless.html").read_text(encoding="utf-8"))


def test_papers_report_shows_payloads_as_text_only(papers_reports):
    html, baseline = papers_reports
    page = check_page(html, baseline)
    for payload in PAYLOADS:
        assert _shown(page, payload), payload  # it reached the page, as text
    text = "".join(page.text)
    assert "claim" in text and "paper 002" in text.lower()
    assert text.count("alert(1)") >= 50  # claims, notes, provenance, monitors, file names


# --- the validation report (simcred validate) ---------------------------------------------------

def _runs(traces, prefix: str, signal: str | None):
    ids = tuple(f"{prefix}{i:03d}{PAYLOADS[i % len(PAYLOADS)]}" for i in range(traces.n_runs))
    signals = tuple(signal if s == "x" and signal else s for s in traces.signals)
    return dataclasses.replace(traces, run_ids=ids, signals=signals)


def _validation(folder: Path, *, poisoned: bool) -> Path:
    folder.mkdir()
    signal = f"x{PAYLOADS[0]}" if poisoned else None
    names = {}
    for key, traces in {"ref": universe(100, 150, seed=1),
                        "sim": universe(100, 150, seed=2, effect=0.15, v_switch=20, name="sim"),
                        "twin": universe(100, 150, seed=3, name="twin")}.items():
        name = f"{key}{PAYLOADS[len(names) + 1].replace('/', '|')}.parquet" if poisoned \
            else f"{key}.parquet"
        (_runs(traces, key, signal) if poisoned else traces).write(folder / name)
        names[key] = name
    document = {
        "name": f"synthetic{''.join(PAYLOADS)}" if poisoned else "synthetic",
        "test_case": {"conditions": "10 <= v <= 25", "tolerance": {signal or "x": 0.5}},
        "reference": {"path": names["ref"]},
        "candidates": {"sim": {"runs": {"path": names["sim"]}, "cost": 1}},
        "features": [signal or "x"],
        "conditions": {"v": {"unit": "m/s", "edges": [5, 10, 15, 20, 25, 30]}},
        "comparison": {"bins": 4, "permutations": 99, "seed": 7},
        "min_data": {"runs": 8, "samples": 200},
        "monitor": [{"path": names["twin"]}],
    }
    path = folder / "validation.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def validation_reports(tmp_path_factory) -> tuple[Path, str, str]:
    root = tmp_path_factory.mktemp("validation-payloads")
    pages = []
    for poisoned in (True, False):
        path = _validation(root / str(poisoned), poisoned=poisoned)
        out = root / f"out-{poisoned}"
        assert run(["-q", "validate", str(path), "--out", str(out)]) == 1
        pages.append(out / "report.html")
    return pages[0], pages[0].read_text(encoding="utf-8"), pages[1].read_text(encoding="utf-8")


def test_validation_report_shows_payloads_as_text_only(validation_reports):
    _, html, baseline = validation_reports
    page = check_page(html, baseline)
    text = "".join(page.text)
    assert f"synthetic{''.join(PAYLOADS)}" in text  # the name, whole, as text
    for payload in PAYLOADS[1:4]:
        assert payload.replace("/", "|") in text  # the trace files' names


@pytest.mark.slow
def test_both_reports_stay_inert_in_chromium(chromium, papers_reports, validation_reports,
                                             tmp_path):
    """After the browser parsed the pages and their own scripts ran: still no foreign script,
    handler or reference (the DOM Chromium dumps)."""
    papers_html, papers_baseline = papers_reports
    validation_path, _, validation_baseline = validation_reports
    page = tmp_path / "papers.html"
    page.write_text(papers_html, encoding="utf-8")
    for path, baseline, name in ((page, papers_baseline, "papers"),
                                 (validation_path, validation_baseline, "validation")):
        own = tmp_path / f"{name}-own.html"
        own.write_text(baseline, encoding="utf-8")
        dumps = [headless(chromium, tmp_path / f"{name}-{k}", "--dump-dom",
                          "--virtual-time-budget=3000", p.resolve().as_uri()).stdout
                 for k, p in enumerate((path, own))]
        assert "<body" in dumps[0] and "<body" in dumps[1], name
        dom, dom_own = Page(dumps[0]), Page(dumps[1])
        assert sorted(dom.handlers) == sorted(dom_own.handlers), name
        assert dom.scripts == dom_own.scripts, name
        for tag, attribute, value in dom.urls:
            assert value.startswith(("data:image/png;base64,", "#")), (name, tag, attribute)
