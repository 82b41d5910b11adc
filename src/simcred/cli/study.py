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


@study_app.command("car-following")
@one_line_errors
def car_following(
    out: Annotated[Path, typer.Option(help="Directory for study.json (findings, provenance), "
                                           "matrix.csv/png, bands/*.csv, maps/*.png, "
                                           "comparisons/*.json.")],
    models: Annotated[str, typer.Option(help="SUMO car-following models replaying the human "
                                             "episodes' leaders.")] = "Krauss,IDM,EIDM,ACC",
    bands: Annotated[str, typer.Option(help="Operating regions: bands of the leader's mean "
                                            "speed [m/s], LOW-HIGH,...")] = "0-10,10-20,20-30",
    features: Annotated[str, typer.Option(help="State features: gap [m], dv [m/s] "
                                               "(leader − follower), v [m/s], a [m/s²], "
                                               "v_leader [m/s].")
                        ] = "gap,dv,a",
    bins: Annotated[int, typer.Option(help="Equal-frequency bins per feature.")] = 5,
    sample_step: Annotated[float, typer.Option(help="Sample period of the compared chains [s] "
                                                    "(a multiple of 0.1 s).")] = 0.5,
    test: Annotated[str, typer.Option(help="runs: run-level test (episodes reassigned; "
                                           "calibrated, the default); permutation: the interim "
                                           "per-transition test with Fisher's combination "
                                           "(anti-conservative on real runs).")
                    ] = "runs",
    alpha: Annotated[float, typer.Option(help="Level of the chain-level test and of the "
                                              "family-wise per-state verdicts.")] = 0.01,
    permutations: Annotated[int, typer.Option(help="Permutations per test.")] = 999,
    baseline: Annotated[int, typer.Option(help="Same-model baseline per cell (run-level test): "
                                               "random half-splits of the reference episodes; "
                                               "0 = none.")] = 10,
    one_sided: Annotated[str, typer.Option(help="Run-level test: a state visited by one set "
                                                "only counts as evidence of a difference, or "
                                                "as neutral.")] = "evidence",
    seed: Annotated[int, typer.Option(help="Study seed (SUMO seeds, splits and tests derive "
                                           "from it).")] = 0,
    max_episodes: Annotated[int | None, typer.Option(help="Use at most this many human and "
                                                          "ACC episodes each (evenly spread).")
                            ] = None,
    min_runs: Annotated[int, typer.Option(help="Fewest episodes per side for a verdict.")] = 10,
    source: Annotated[Path | None, typer.Option(help="OpenACC files (CSV or Parquet; default: "
                                                     "the copy shipped with simcred).")] = None,
    workers: Workers = None,
    scheduler: Scheduler = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
    as_json: Json = False,
) -> None:
    """Real human car following (OpenACC) vs SUMO models and real ACC, per speed band."""
    from simcred import data
    from simcred.report.study import study_figures
    from simcred.study import StudyOptions, run_study, write_study

    options = StudyOptions(models=_names(models), bands=_bands(bands), features=_names(features),
                           bins=bins, sample_step=sample_step, test=test, alpha=alpha,
                           permutations=permutations, baseline=baseline,
                           one_sided=one_sided, seed=seed,
                           min_runs=min_runs,
                           max_episodes=max_episodes)
    inputs = [source if source is not None else data.path("openacc")]
    with writing(out, *inputs, overwrite=overwrite, resume=resume) as target, \
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

    table = Table(title=f"vs real human following — {result.to_dict()['method']}")
    table.add_column("row")
    for band in result.options.bands:
        table.add_column(f"leader {band_label(band)}", justify="right")
    for row in result.rows:
        cells = []
        for band in result.options.bands:
            c = result.cell(row, band)
            if c.verdict is None:
                cells.append("[dim]insufficient data[/dim]")
            else:
                color = "red" if c.verdict.rejected else "green"
                base = c.comparison.baseline
                halves = "" if base is None else \
                    f" (halves {100 * base.low:.1f}-{100 * base.high:.1f}%)"
                cells.append(f"[{color}]p={c.verdict.pvalue:.2g} d={100 * c.distance:.1f}%"
                             f"{halves}[/{color}]")
        table.add_row(row, *cells)
    out_console.print(table)
    out_console.print(f"wrote {out}/study.json, matrix.csv, matrix.png, headway.png, bands/, "
                      "maps/, comparisons/", highlight=False)
