"""Writing a reprocessing result to a directory (``simcred reprocess --out DIR``).

The figures (``figures/``, Figs. 3-7) are drawn by
:func:`simcred.report.reprocessing.write_reprocessed`, which calls :func:`write` and then draws
them (reprocess does not import report).

Layout::

    reprocess.json      summary: options, fits, sensor model, reactions, eqs. (4)-(7), risk
    errors.json         Fig. 4's statistics: sensor -> step -> object -> quantity -> stats
    reaction.json       reactions (time, manoeuvre) and eqs. (4)-(7)
    risk.json           risk, TTC and THW time series of every assessed representation
    descriptions/       every scenario description (JSON), e.g. fit_GT.json, fit_rGT_sb.json
    scenario.xosc       OpenSCENARIO export of the measurement's description (GT, else SD),
                        in map coordinates (:mod:`simcred.reprocess.map_export`)
    scenario.xodr       its RoadNetwork: a CommonRoad scenario's lanelets as OpenDRIVE
    resimulations/      every resimulation as Parquet, e.g. rGT.parquet
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from simcred._json import dumps, envelope
from simcred.io import parquet
from simcred.reprocess.map_export import write_scenario
from simcred.reprocess.pipeline import Reprocessed
from simcred.reprocess.representation import Rep


def write(result: Reprocessed, directory: str | Path) -> dict[str, Path]:
    """Write everything; returns the main files by role."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    summary = out / "reprocess.json"
    summary.write_text(summary_text(result))
    files = {
        "summary": summary,
        "errors": _json(out / "errors.json", "errors", {
            sensor: {step: {obj: {q: s.to_dict() for q, s in by_q.items()}
                            for obj, by_q in by_obj.items()}
                     for step, by_obj in table.items()}
            for sensor, table in result.errors.items()}, result.inputs),
        "reaction": _json(out / "reaction.json", "reaction", {
            "reactions": {k: r.to_dict() for k, r in result.reactions.items()},
            "analysis": result.analysis_report}, result.inputs),
        "risk": _json(out / "risk.json", "risk",
                      {k: r.to_dict() for k, r in result.risk.items()}, result.inputs),
    }
    (out / "descriptions").mkdir(exist_ok=True)
    for name, description in result.descriptions.items():
        description.write(out / "descriptions" / f"{Rep(name).file_stem}.json")
    for name, traces in result.resimulations.items():
        (out / "resimulations").mkdir(exist_ok=True)
        parquet.write(traces, out / "resimulations" / f"{Rep(name).file_stem}.parquet")
    files.update(write_scenario(result, out))
    return files


def summary_text(result: Reprocessed) -> str:
    """``reprocess.json``'s text (what ``simcred reprocess --json`` prints)."""
    return dumps(envelope("reprocess", result.to_dict(), inputs=result.inputs))


def _json(path: Path, kind: str, body: dict[str, Any], inputs: dict[str, str]) -> Path:
    path.write_text(dumps(envelope(kind, body, inputs=inputs)))
    return path
