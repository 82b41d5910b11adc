"""simcred study: validity studies on real data, end to end."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from simcred.cli._app import (
    Json,
    Scheduler,
    State,
    Workers,
    _emit,
    app,
    one_line_errors,
    out_console,
    progress,
)
from simcred.cli._writing import Overwrite, Resume, writing
from simcred.errors import OptionError

study_app = typer.Typer(help="Validity studies on real data (data → simulation → comparison).")
app.add_typer(study_app, name="study")


def _bands(text: str) -> tuple[tuple[float, float], ...]:
    bands = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        lo, sep, hi = part.partition("-")
        try:
            bands.append((float(lo), float(hi)))
        except ValueError:
            raise OptionError(f"--bands: {part!r} is not LOW-HIGH in m/s (e.g. 0-10,10-20)"
                              ) from None
        if not sep:
            raise OptionError(f"--bands: {part!r} is not LOW-HIGH in m/s (e.g. 0-10,10-20)")
    return tuple(bands)


def _names(text: str) -> tuple[str, ...]:
    return tuple(p.strip() for p in text.split(",") if p.strip())


def _tolerance(text: str | None) -> dict[str, float]:
    """``v=0.1`` or ``v=0.1,gap=0.5`` (per response feature, in its unit per second)."""
    if not text:
        return {}
    try:
        pairs = [part.split("=") for part in text.split(",") if part.strip()]
        return {name.strip(): float(value) for name, value in pairs}
    except ValueError:
        raise OptionError(f"--tolerance must be FEATURE=NUMBER,... (e.g. v=0.1); got {text!r}"
                          ) from None


#: Options of the run-level study that the response comparison replaced (one-line errors).
REMOVED = {
    "--test": "the study now uses the response comparison of simcred validate (the run-level "
              "and per-transition tests are `simcred compare --test runs|permutation`)",
    "--one-sided": "the response comparison has no one-sided rule (a state one set never "
                   "visits does not enter the deviation)",
    "--baseline": "the human-vs-human rows are the baseline (halves of the band's episodes and "
                  "cars, in the same response comparison)",
}


def _refuse_removed(**given: object) -> None:
    for name, value in given.items():
        option = "--" + name.replace("_", "-")
        if value is not None:
            raise OptionError(f"{option} was removed: {REMOVED[option]}")


@study_app.command("car-following")
@one_line_errors
def car_following(
    out: Annotated[Path, typer.Option(help="Directory for study.json (findings, provenance), "
                                           "matrix.csv/png, bands/*.csv, maps/*.png, "
                                           "comparisons/*.json.")],
    models: Annotated[str, typer.Option(help="SUMO car-following models replaying the human "
                                             "episodes' leaders.")] = "Krauss,IDM,EIDM,ACC",
    bands: Annotated[str, typer.Option(help="Operating regions: contiguous bands of the "
                                            "leader's speed [m/s], LOW-HIGH,...; episodes are "
                                            "cut into per-band segments.")
                     ] = "0-10,10-20,20-30",
    features: Annotated[str, typer.Option(help="State features: gap [m], dv [m/s] "
                                               "(leader − follower), v [m/s], a [m/s²], "
                                               "v_leader [m/s].")
                        ] = "gap,v,v_leader",
    inputs: Annotated[str, typer.Option(help="Exogenous features (conditioned on, not "
                                             "compared): the recorded leader.")] = "v_leader",
    tolerance: Annotated[str | None, typer.Option(
        help="Largest acceptable response deviation per feature, in its unit per second "
             "(v=0.1: the acceleration response within 0.1 m/s²); with it each cell is valid / "
             "not valid / inconclusive, without it deviations are reported, not judged.")
    ] = None,
    bins: Annotated[int, typer.Option(help="Equal-frequency bins per feature.")] = 3,
    sample_step: Annotated[float, typer.Option(help="Segments resampled to this period [s] "
                                                    "before the comparison.")] = 0.5,
    alpha: Annotated[float, typer.Option(help="Level of the difference test and of the "
                                              "deviation's bounds (Bonferroni over the bands "
                                              "for 'not valid').")] = 0.05,
    permutations: Annotated[int, typer.Option(help="Permutations of the difference test.")
                            ] = 199,
    bootstrap: Annotated[int, typer.Option(help="Cluster-bootstrap replicates of the "
                                                "deviation's bounds.")] = 500,
    seed: Annotated[int, typer.Option(min=0, help="Study seed: the SUMO replays' campaign seed; "
                                           "splits and comparisons per (row, band) from it.")
                    ] = 0,
    max_episodes: Annotated[int | None, typer.Option(help="Use at most this many human and "
                                                          "ACC episodes each (evenly spread).")
                            ] = None,
    min_runs: Annotated[int, typer.Option(help="Fewest design units (episodes, pairs) per side "
                                               "and band; below, the cell is unknown.")] = 10,
    min_samples: Annotated[int, typer.Option(help="Fewest samples (at 0.1 s) per side and "
                                                  "band.")] = 500,
    min_length: Annotated[int, typer.Option(help="Shortest segment kept [samples at 0.1 s].")
                          ] = 25,
    source: Annotated[Path | None, typer.Option(help="OpenACC files (CSV or Parquet; default: "
                                                     "the copy shipped with simcred).")] = None,
    test: Annotated[str | None, typer.Option(hidden=True)] = None,
    one_sided: Annotated[str | None, typer.Option(hidden=True)] = None,
    baseline: Annotated[str | None, typer.Option(hidden=True)] = None,
    workers: Workers = None,
    scheduler: Scheduler = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
    as_json: Json = False,
) -> None:
    """Real human car following (OpenACC) vs SUMO models and real ACC, per speed band: the
    response deviation with its interval (simcred validate's engine, without a test case)."""
    from simcred import data
    from simcred.report.study import study_figures
    from simcred.study import StudyOptions, run_study, write_study

    _refuse_removed(test=test, one_sided=one_sided, baseline=baseline)
    options = StudyOptions(models=_names(models), bands=_bands(bands), features=_names(features),
                           inputs=_names(inputs), tolerance=_tolerance(tolerance), bins=bins,
                           sample_step=sample_step, alpha=alpha, permutations=permutations,
                           bootstrap=bootstrap, seed=seed, min_runs=min_runs,
                           min_samples=min_samples, min_length=min_length,
                           max_episodes=max_episodes)
    inputs_ = [source if source is not None else data.path("openacc")]
    with writing(out, *inputs_, overwrite=overwrite, resume=resume) as target, \
            target.engine(workers, scheduler) as runner:
        result = run_study(options, source=source, runner=runner,
                           progress=progress("SUMO replays (chunks)"))
        write_study(result, target.path)
        study_figures(result, target.path)
    if not as_json and not State.quiet:
        _print(result, out)
    _emit(result.to_dict(), as_json, "")


def _print(result, out: Path) -> None:
    from simcred.study.car_following import band_label

    judged = ", ".join(f"{k} ≤ {v:g}" for k, v in result.options.tolerance.items())
    table = Table(title="response deviation vs real human following [95 % interval], "
                        f"difference p — {'tolerance ' + judged if judged else 'no tolerance'}")
    table.add_column("row")
    for band in result.options.bands:
        table.add_column(f"leader {band_label(band)}", justify="right")
    colors = {"valid": "green", "not valid": "red", "inconclusive": "yellow"}
    for row in result.rows:
        cells = []
        for band in result.options.bands:
            r = result.cell(row, band).result
            if r.comparison is None:
                cells.append(f"[dim]unknown ({r.reference_units} vs {r.candidate_units})[/dim]")
                continue
            text = " ".join(f"{b.feature} {b.estimate:.2g} [{b.low:.2g}, {b.high:.2g}]"
                            for b in r.bounds) + f" p={r.pvalue:.2g}"
            color = colors.get(r.status.value)
            cells.append(f"[{color}]{text} {r.status.value}[/{color}]" if color else text)
        table.add_row(row, *cells)
    out_console.print(table)
    out_console.print(f"wrote {out}/study.json, matrix.csv, matrix.png, headway.png, bands/, "
                      "maps/, comparisons/", highlight=False)
