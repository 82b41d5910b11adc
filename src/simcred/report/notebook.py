"""Notebook display (``_repr_html_``): a summary table and a figure per simcred object.

:func:`html` draws a :class:`~simcred.traces.TraceSet` (runs table, first signal over time), a
:class:`~simcred.compare.result.Comparison` (verdict table, the state map), a
:class:`~simcred.compare.pairwise.DistanceMatrix` (the matrix, the heatmap) and a
:class:`~simcred.validate.loop.Validation` (verdicts, the ranking figure). Figures are inline
PNG (``data:`` URIs), so a notebook saved to HTML keeps them. The domain objects reach this
module through :mod:`simcred._display` (they do not import the report layer).
"""

from __future__ import annotations

import base64
import html as markup
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from simcred.compare.pairwise import DistanceMatrix  # noqa: E402
from simcred.compare.result import Comparison  # noqa: E402
from simcred.report.figures import distance_heatmap, save_figure, state_map  # noqa: E402
from simcred.report.validate import ranking_figure  # noqa: E402
from simcred.traces import TraceSet  # noqa: E402
from simcred.validate.loop import Validation  # noqa: E402

MAX_RUNS = 10  # runs listed and drawn for a trace set
STYLE = ("<style>.simcred table{border-collapse:collapse;margin:.3em 0}"
         ".simcred td,.simcred th{border:1px solid #ccc;padding:2px 8px;text-align:left}"
         ".simcred img{max-width:100%}</style>")


def html(obj: Any) -> str:
    """The HTML of ``obj``: a ``<div class="simcred">`` with tables and inline figures."""
    for kind, render in RENDERERS:
        if isinstance(obj, kind):
            return f'{STYLE}<div class="simcred">{"".join(render(obj))}</div>'
    raise TypeError(f"no notebook display for {type(obj).__name__}")


# -- pieces ----------------------------------------------------------------------------------------


def _table(rows: Iterable[tuple[Any, ...]], header: tuple[str, ...] | None = None) -> str:
    head = "" if header is None else "<tr>" + "".join(
        f"<th>{markup.escape(h)}</th>" for h in header) + "</tr>"
    body = "".join("<tr>" + "".join(f"<td>{markup.escape(_text(c))}</td>" for c in row) + "</tr>"
                   for row in rows)
    return f"<table>{head}{body}</table>"


def _text(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def _figure(draw: Callable[[Path], Path], alt: str) -> str:
    """An ``<img>`` with the PNG that ``draw(path)`` writes, inline."""
    with tempfile.TemporaryDirectory(prefix="simcred-display-") as tmp:
        png = draw(Path(tmp) / "figure.png").read_bytes()
    data = base64.b64encode(png).decode("ascii")
    return f'<img alt="{markup.escape(alt)}" src="data:image/png;base64,{data}"/>'


def _title(text: str) -> str:
    return f"<h4>{markup.escape(text)}</h4>"


# -- trace sets ------------------------------------------------------------------------------------


def _traceset(ts: TraceSet) -> list[str]:
    units = ts.units
    signals = ", ".join(f"{s} [{units[s]}]" if s in units else s for s in ts.signals)
    summary = _table([("source", ts.source), ("runs", ts.n_runs), ("rows", ts.n_rows),
                      ("signals", signals),
                      ("metadata", ", ".join(sorted(map(str, ts.metadata))) or "none")])
    runs = _table(((ts.run_ids[i], int(ts.lengths[i]), float(ts.run(i)["t"][0]),
                    float(ts.run(i)["t"][-1])) for i in range(min(ts.n_runs, MAX_RUNS))),
                  ("run", "steps", "t first [s]", "t last [s]"))
    more = f"<p>… and {ts.n_runs - MAX_RUNS} more runs</p>" if ts.n_runs > MAX_RUNS else ""
    first = ts.signals[0]
    return [_title(f"TraceSet: {ts.n_runs} runs"), summary, runs, more,
            _figure(lambda path: _signal_figure(ts, first, path), f"{first} over time")]


def _signal_figure(ts: TraceSet, signal: str, path: Path) -> Path:
    fig, ax = plt.subplots(figsize=(7, 3), constrained_layout=True)
    for i in range(min(ts.n_runs, MAX_RUNS)):
        run = ts.run(i)
        ax.plot(run["t"], run[signal], linewidth=1, label=ts.run_ids[i])
    unit = ts.units.get(signal)
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"{signal} [{unit}]" if unit else signal)
    if ts.n_runs <= 5:
        ax.legend(fontsize=7)
    return save_figure(fig, path)


# -- comparisons -----------------------------------------------------------------------------------


def _comparison(c: Comparison) -> list[str]:
    a, b = c.inputs
    o = c.options
    start = c.start
    rows = [("A", f"{a.source} ({a.runs} runs)"), ("B", f"{b.source} ({b.runs} runs)"),
            ("features", ", ".join(c.space.features)), ("states |S|", c.n_states),
            ("test", f"{o.kernel} kernel, {o.test} test, α = {o.alpha}"),
            ("start distributions", "differ" if start.rejected else "not distinguished"),
            ("tested states", len(c.states)), ("rejected states", len(c.rejected_states)),
            ("untestable states", len(c.untestable)),
            ("distance", "stopped at the start test" if c.distance is None
             else f"{100 * c.distance:.2f} %")]
    if c.chain is not None:
        rows.append(("chain verdict", f"{'differ' if c.chain.rejected else 'same'} "
                                      f"(p = {c.chain.pvalue:.4g})"))
    parts = [_title("Comparison"), _table(rows)]
    if all(len(e) > 0 for e in c.space.edges[:2]):  # a constant feature has no grid to draw
        parts.append(_figure(lambda path: state_map(c, path), "state map"))
    return parts


def _matrix(m: DistanceMatrix) -> list[str]:
    rows = [(name, *(("start ≠" if v != v else f"{100 * v:.2f} %") for v in row))
            for name, row in zip(m.names, m.distances, strict=True)]
    return [_title("Distance matrix"), _table(rows, ("", *m.names)),
            _figure(lambda path: distance_heatmap(m, path), "distance heatmap")]


# -- validations -----------------------------------------------------------------------------------


def _validation(v: Validation) -> list[str]:
    parts = [_title(f"Validation: {v.verdict}"), f"<p>{markup.escape(v.summary)}</p>",
             _table(((c.candidate, c.verdict, "; ".join(c.reasons))
                     for c in v.candidates.values()), ("candidate", "verdict", "reasons"))]
    if any(r.score is not None for r in v.ranking):
        parts.append(_figure(lambda path: ranking_figure(v, path), "ranking"))
    return parts


RENDERERS: tuple[tuple[type, Callable[[Any], list[str]]], ...] = (
    (TraceSet, _traceset), (Comparison, _comparison), (DistanceMatrix, _matrix),
    (Validation, _validation))
