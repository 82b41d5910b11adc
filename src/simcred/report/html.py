"""The self-contained HTML report of a ``simcred paper all`` directory (``simcred report DIR``).

One page, ``DIR/index.html``: the overall claims score, one section per paper (what was run,
the claims, the figures, and for paper 003 the configuration, the quotient and the monitors'
findings) and the run's provenance. Every figure is embedded as a ``data:image/png`` URI and the
CSS is inline, so the file can be mailed or attached as it is; it refers to no URL.

The page is deterministic: the same directory gives a byte-identical file (there is no timestamp,
files are visited in sorted order and JSON objects in their stored order). Missing parts of a
partially written directory are named on the page instead of failing; only a missing directory
or a missing/unreadable top-level ``claims.json`` is an error.
"""

from __future__ import annotations

import base64
import json
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import jinja2

from simcred.errors import SimcredError
from simcred.outputs import write_atomic

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
MAX_VIOLATIONS = 20  # violations shown per monitor; the count says how many there are
MAX_LIST_ITEMS = 12  # longer lists in the provenance are abbreviated (full value on hover)


@dataclass(frozen=True, slots=True)
class Paper:
    """What the report knows about one paper: its method and its figures, in order."""

    key: str
    title: str
    method: str
    figures: tuple[tuple[str, str], ...]  # (path inside paperNNN/, caption)


PAPERS = {
    "000": Paper(
        "000", "Neurohr et al. 2023: Determining the Validity of Simulation Models for the "
        "Verification of ADSs",
        "Sets of runs become Markov chains over a discretized state space; an MMD two-sample "
        "test per state decides which transitions differ, and the fraction of distinguishable "
        "transitions is the distance between two models (sec. VI: SimpleCar λ sweep and the "
        "T-junction with occlusion).",
        (("fig5_inputs.png", "Fig. 5: the input functions for the steering speed and the "
          "velocity of the SimpleCar (sec. VI-A), and resulting paths."),
         ("fig6_xy.png", "Fig. 6: performance of the kernels on SimpleCar data sets with "
          "λ ∈ {0.81, 0.82, …, 1.2}, features x and y: distance to the λ = 1.0 baseline."),
         ("fig7_xy_heading.png", "Fig. 7: the same with x, y and the heading ψ as features."),
         ("table3_bound.png", "Table 3: distances between T-junction data sets without "
          "occlusion, with occlusion and with a chance of occlusion (the paper's bound test)."),
         ("table3_permutation.png", "Table 3 with a permutation test instead of the bound "
          "test."))),
    "002": Paper(
        "002", "Wagner, Groh et al.: Towards Cross-Verification and Use of Simulation in the "
        "Assessment of Automated Driving",
        "A real drive is reprocessed: scenario fit, resimulation, refit and risk (TTR); the "
        "errors of every step are isolated, a scenario-based sensor model removes the EGO's "
        "behaviour change, and local variations of the cut-in are simulated (sec. V).",
        (("figures/fig3_fit.png", "Fig. 3: the scenario description fitted to GT (thin lines) "
          "over the GT data (thick lines): position, velocity and heading; EGO blue, TO green."),
         ("figures/fig4_errors.png", "Fig. 4: errors of the reprocessing pipeline for distance "
          "d, velocity v and heading θ (rows) per pipeline step; boxes from the 25 % to the "
          "75 % quantile, whiskers to the full extent, diamonds mean ± std (ideal sensor)."),
         ("figures/fig4_errors_scenario_based.png", "Fig. 4 with the scenario-based sensor "
          "model (sec. IV) in the resimulation."),
         ("figures/fig5_sd_velocity.png", "Fig. 5: the fit of SD compared to the GT and SD "
          "traces: the fit converges towards GT and so corrects the error in SD."),
         ("figures/fig6_traces.png", "Fig. 6: the GT trace compared to the GT and SD "
          "resimulations around the EGO's reaction."),
         ("figures/fig7_velocity_risk.png", "Fig. 7: EGO velocity of GT and of both "
          "resimulations (the TO's for reference), and below the risk measure of the same "
          "cases."),
         ("variations/figures/fig8_variations.png", "Fig. 8: the simulations of the variations "
          "of the original scenario compared to the resimulation of GT by trace (upper), "
          "velocity (middle) and risk (lower); TO purple, EGO blue, rGT's risk green."))),
    "003": Paper(
        "003", "Braun et al.: A Concept for Semi-Automatic Configuration of Sufficiently Valid "
        "Simulation Setups",
        "Simulation models carry assume-guarantee contracts: the cheapest setup whose "
        "composition refines a test case's requirement is configured, a quotient says what a "
        "missing model must satisfy, and monitors check that recorded runs stayed inside the "
        "models' validity domains.",
        ()),
}

INTRO = ("simcred tells teams who test automated driving in simulation whether a simulation is "
         "valid enough for a given test case. It implements three published methods as one "
         "system: the distance between sets of runs (Neurohr et al.), the reprocessing of real "
         "drives into simulation (Wagner, Groh et al.) and the configuration of sufficiently "
         "valid simulation setups with contracts (Braun et al.). This report regenerates the "
         "papers' experiments and checks each paper's qualitative claims on simcred's own "
         "numbers.")


def write_report(directory: str | Path, *, out: str | Path | None = None) -> Path:
    """Write the self-contained HTML report of a ``simcred paper all`` directory.

    Parameters
    ----------
    directory : str or Path
        The output directory of ``simcred paper all --out DIR``: ``claims.json`` and the
        ``paper000/``, ``paper002/``, ``paper003/`` folders (any of them may be missing).
    out : str or Path, optional, default: ``directory / "index.html"``
        The HTML file to write.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    SimcredError
        ``directory`` does not exist or has no readable ``claims.json``.
    """
    directory, out = _write_report_iv(directory, out)
    return write_atomic(out, render_report(directory))


def render_report(directory: str | Path) -> str:
    """The report's HTML text (see :func:`write_report`)."""
    directory = Path(directory)
    document = _top_claims(directory)
    # a claims.json written before issue 27 calls the papers "seeds"
    papers_doc = document.get("papers", document.get("seeds"))
    papers_doc = papers_doc if isinstance(papers_doc, dict) else {}
    keys = list(PAPERS) + sorted(k for k in papers_doc if k not in PAPERS)
    papers = [_paper(directory, key, papers_doc.get(key)) for key in keys]
    claims = [c for p in papers for c in p["claims"]]
    holding = sum(c["status"] == "pass" for c in claims)
    context = {
        "title": "simcred report: the papers' claims, checked",
        "intro": INTRO,
        "directory": directory.name or str(directory),
        "score": {"holding": holding, "total": len(claims),
                  "failing": [c for c in claims if c["status"] != "pass"]},
        "papers": papers,
        "run": _run(document, papers),
    }
    return _environment().get_template("report.html.j2").render(context)


def _write_report_iv(directory: str | Path, out: str | Path | None) -> tuple[Path, Path]:
    directory = Path(directory)
    if not directory.is_dir():
        raise SimcredError(f"{directory}: no such directory (expected the output of "
                           f"simcred paper all --out DIR)")
    out = directory / "index.html" if out is None else Path(out)
    if out.is_dir():
        raise SimcredError(f"{out}: is a directory; --out names the HTML file to write")
    return directory, out


def _environment() -> jinja2.Environment:
    return jinja2.Environment(loader=jinja2.PackageLoader("simcred.report", "templates"),
                              autoescape=True, undefined=jinja2.StrictUndefined,
                              trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True)


def _read_json(path: Path) -> tuple[Any, str | None]:
    """The parsed file, or ``None`` and a one-line reason."""
    if not path.is_file():
        return None, f"{path.name} is missing"
    try:
        return json.loads(path.read_text(encoding="utf-8")), None
    except (OSError, UnicodeDecodeError) as exc:
        return None, f"{path.name} is unreadable ({exc.__class__.__name__})"
    except json.JSONDecodeError as exc:
        return None, f"{path.name} is not valid JSON (line {exc.lineno}, column {exc.colno})"
    except (RecursionError, ValueError):
        return None, f"{path.name} is not valid JSON (nested too deeply or a number too long)"


def _top_claims(directory: Path) -> dict:
    path = directory / "claims.json"
    if not path.is_file():
        raise SimcredError(f"{path}: no such file (expected the output of simcred paper all "
                           f"--out {directory})")
    document, problem = _read_json(path)
    if problem is not None:
        raise SimcredError(f"{path}: {problem.partition(' ')[2]}")
    if not isinstance(document, dict):
        raise SimcredError(f"{path}: expected a JSON object, got {type(document).__name__}")
    if document.get("kind") != "claims_all":
        raise SimcredError(f"{path}: kind is {document.get('kind')!r}, expected 'claims_all' "
                           f"(the claims of simcred paper all)")
    return document


def _paper(directory: Path, key: str, entry: Any) -> dict:
    """Everything the template shows for one paper, with the missing parts named."""
    known = PAPERS.get(key, Paper(key, f"paper {key}", "", ()))
    folder = directory / f"paper{key}"
    problems: list[str] = []
    if not isinstance(entry, dict):
        fallback, problem = _read_json(folder / "claims.json")
        if isinstance(fallback, dict):
            entry = fallback
            problems.append(f"claims.json has no entry for paper {key}; shown from "
                            f"paper{key}/claims.json")
        else:
            entry = {}
            reason = "is not a JSON object" if problem is None else problem.partition(" ")[2]
            problems.append(f"not run: claims.json has no entry for paper {key} and "
                            f"paper{key}/claims.json {reason}")
    raw_claims = entry.get("claims")
    if raw_claims is not None and not isinstance(raw_claims, list):
        problems.append("the claims are not a list")
        raw_claims = None
    claims = [_claim(key, c) for c in raw_claims or [] if isinstance(c, dict)]
    if raw_claims is not None and len(claims) < len(raw_claims):
        problems.append(f"{len(raw_claims) - len(claims)} claim(s) are not JSON objects")
    provenance = entry.get("provenance")
    figures, missing = _figures(folder, known.figures)
    paper = {
        "key": key,
        "anchor": f"paper-{key}",
        "title": str(entry.get("title") or known.title),
        "method": known.method,
        "folder": folder.name,
        "folder_exists": folder.is_dir(),
        "problems": problems,
        "experiments": _experiments(provenance),
        "provenance": _flatten(provenance) if isinstance(provenance, dict) else [],
        "claims": claims,
        "holding": sum(c["status"] == "pass" for c in claims),
        "figures": figures,
        "missing_figures": missing,
        "findings": None,
    }
    if key == "003":
        paper["findings"] = _findings(folder)
    return paper


def _claim(paper: str, claim: dict) -> dict:
    identifier = _text(claim.get("id"))
    return {"id": identifier, "anchor": f"claim-{paper}-{identifier}", "paper": paper,
            "claim": _text(claim.get("claim")), "value": _text(claim.get("value")),
            "bound": _text(claim.get("bound")), "status": _status(claim.get("passed")),
            "note": "" if claim.get("note") is None else _text(claim.get("note"))}


def _text(value: Any) -> str:
    """A value as the page shows it: numbers to 4 significant digits, None as a dash."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, str):
        return value
    if isinstance(value, int):
        return str(value)
    return json.dumps(value, ensure_ascii=False)


def _flatten(value: Any, prefix: str = "") -> list[dict]:
    """Nested dicts (and lists of dicts) as rows ``a.b.c = value``."""
    if isinstance(value, dict) and value:
        rows = []
        for k, v in value.items():
            rows += _flatten(v, f"{prefix}.{k}" if prefix else str(k))
        return rows
    if isinstance(value, list) and value and any(isinstance(v, dict | list) for v in value):
        rows = []
        for i, v in enumerate(value):
            rows += _flatten(v, f"{prefix}.{i}" if prefix else str(i))
        return rows
    full = "{}" if value == {} else _text(value)
    shown, title = full, ""
    if isinstance(value, list) and len(value) > MAX_LIST_ITEMS:
        head = ", ".join(_text(v) for v in value[:3])
        shown = f"[{head}, …, {_text(value[-1])}] ({len(value)} values)"
        title = full
    return [{"key": prefix or "(value)", "value": shown, "title": title}]


def _experiments(provenance: Any) -> list[str]:
    """One line per experiment of the provenance (its name, runs, sizes and seed), and one for
    the provenance's top-level settings, if any."""
    if not isinstance(provenance, dict):
        return []

    def scalars(part: dict) -> list[str]:
        return [f"{k} = {_text(v)}" for k, v in part.items() if not isinstance(v, dict | list)]

    settings = scalars(provenance)
    lines = [", ".join(settings[:6]) + (", …" if len(settings) > 6 else "")] if settings else []
    for name, part in provenance.items():
        if not isinstance(part, dict):
            continue
        facts = [f"{k} = {_text(part[k])}" for k in ("experiment", "runs", "n",
                                                     "sets_per_category", "seed")
                 if k in part and not isinstance(part[k], dict | list)] or scalars(part)[:6]
        lines.append(f"{name}: {', '.join(facts)}" if facts else str(name))
    return lines


def _figures(folder: Path, known: tuple[tuple[str, str], ...]) -> tuple[list[dict], list[str]]:
    """The known figures in the paper's order, then every other PNG of the folder (sorted)."""
    figures, missing = [], []
    for relative, caption in known:
        if (folder / relative).is_file():
            figures.append(_figure(folder, relative, caption))
        else:
            missing.append(relative)
    names = {relative for relative, _ in known}
    extras = sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*.png")
                    if p.is_file()) if folder.is_dir() else []
    figures += [_figure(folder, relative, relative) for relative in extras
                if relative not in names]
    return figures, missing


def _figure(folder: Path, relative: str, caption: str) -> dict:
    figure = {"path": f"{folder.name}/{relative}", "caption": caption, "uri": "", "width": 0,
              "height": 0, "problem": ""}
    try:
        data = (folder / relative).read_bytes()
    except OSError as exc:
        return {**figure, "problem": f"unreadable ({exc.__class__.__name__})"}
    if not (data.startswith(PNG_SIGNATURE) and data[12:16] == b"IHDR" and len(data) >= 24):
        return {**figure, "problem": "not a PNG file (or an incompletely written one)"}
    width, height = struct.unpack(">II", data[16:24])
    uri = "data:image/png;base64," + base64.b64encode(data).decode("ascii")
    return {**figure, "uri": uri, "width": width, "height": height}


def _findings(folder: Path) -> dict:
    """Paper 003's findings.json: configuration, quotient and monitors, each possibly absent."""
    document, problem = _read_json(folder / "findings.json")
    if problem is None and not isinstance(document, dict):
        problem = "findings.json is not a JSON object"
    if problem is not None:
        return {"problem": f"paper003/{problem}", "library": "", "configuration": None,
                "quotient": None, "monitors": None}
    return {"problem": "", "library": _text(document.get("library")),
            "configuration": _configuration(document.get("configuration")),
            "quotient": _quotient(document.get("quotient")),
            "monitors": _monitors(document.get("monitors"))}


def _configuration(part: Any) -> dict | None:
    if not isinstance(part, dict):
        return None
    setup = part.get("setup")
    return {"test_case": _text(part.get("test_case")),
            "setup": [(_text(k), _text(v)) for k, v in setup.items()]
            if isinstance(setup, dict) else [],
            "cost": _text(part.get("cost")), "verdict": _text(part.get("verdict")),
            "checked_setups": _text(part.get("checked_setups")),
            "explanation": "" if part.get("explanation") is None
            else _text(part.get("explanation"))}


def _quotient(part: Any) -> dict | None:
    if not isinstance(part, dict):
        return None
    accepts, given = part.get("accepts"), part.get("given")
    return {"removed": _text(part.get("removed")), "test_case": _text(part.get("test_case")),
            "configurable_without": _text(part.get("configurable_without")),
            "without_reason": "" if part.get("without_reason") is None
            else _text(part.get("without_reason")),
            "given": [(_text(k), _text(v)) for k, v in given.items()]
            if isinstance(given, dict) else [],
            "requirement": _text(part.get("requirement")),
            "accepts": [(_text(k), _status(v)) for k, v in accepts.items()]
            if isinstance(accepts, dict) else []}


def _monitors(part: Any) -> list[dict] | None:
    if not isinstance(part, list):
        return None
    monitors = []
    for m in part:
        if not isinstance(m, dict):
            continue
        violations = m.get("violations")
        violations = [v for v in violations if isinstance(v, dict)] \
            if isinstance(violations, list) else []
        monitors.append({
            "name": _text(m.get("name")), "runs": _text(m.get("runs")),
            "samples": _text(m.get("samples")), "status": _status(m.get("passed")),
            "total": len(violations),
            "violations": [{k: _text(v.get(k)) for k in ("contract", "kind", "clause", "run",
                                                           "t_start", "t_end", "margin")}
                           for v in violations[:MAX_VIOLATIONS]]})
    return monitors


def _status(value: Any) -> str:
    """A JSON boolean as "pass"/"fail"; anything else is "unknown"."""
    return "pass" if value is True else "fail" if value is False else "unknown"


def _run(document: dict, papers: list[dict]) -> dict:
    """The run record of claims.json, and every (random) seed found in the options and the
    papers' provenances."""
    run = document.get("run")
    run = run if isinstance(run, dict) else {}
    options = _flatten(run.get("options")) if isinstance(run.get("options"), dict) else []
    used = [("run options", row) for row in options]
    used += [(f"paper {p['key']}", row) for p in papers for row in p["provenance"]]
    return {
        "present": bool(run),
        "command": "" if run.get("command") is None else _text(run.get("command")),
        "options": options,
        "versions": _flatten(run.get("versions")) if isinstance(run.get("versions"), dict)
        else [],
        "inputs": [(_text(k), _text(v)) for k, v in run["inputs"].items()]
        if isinstance(run.get("inputs"), dict) else [],
        "seeds": [{"where": where, **row} for where, row in used if _is_seed(row["key"])],
        "simcred_version": _text(document.get("simcred_version")),
        "schema_version": _text(document.get("schema_version")),
    }


def _is_seed(key: str) -> bool:
    last = key.rsplit(".", 1)[-1].lower()
    return last in ("seed", "seeds") or last.endswith("_seed")
