"""simcred paper 000|002|all and simcred report."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from simcred.cli._app import (
    Scheduler,
    State,
    Workers,
    app,
    check_output,
    one_line_errors,
    out_console,
    plain_table,
    progress,
    say,
)
from simcred.cli._writing import Overwrite, Resume, writing
from simcred.limits import check_count

paper_app = typer.Typer(help="Regenerate the papers' experiments and check their claims.")
app.add_typer(paper_app, name="paper")


@paper_app.command("000")
@one_line_errors
def paper_000(
    out: Annotated[Path, typer.Option(help="Directory for figures, tables and claims.json.")],
    runs: Annotated[int | None, typer.Option(help="Runs per trace set (default: the "
                                                  "documented full size).")] = None,
    seed: Annotated[int, typer.Option(min=0, help="Seed of every campaign and test.")] = 0,
    workers: Workers = None,
    scheduler: Scheduler = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
) -> None:
    """Neurohr et al. sec. VI: SimpleCar λ sweep (Figs. 5-7) and T-junction (Table 3)."""
    from simcred.paper import markov_chains

    if runs is not None:
        check_count(runs, "runs", "--runs", minimum=2)
    with writing(out, overwrite=overwrite, resume=resume) as target, \
            target.engine(workers, scheduler) as runner:
        claims = markov_chains.run_all(target.path, runs=runs, seed=seed, runner=runner,
                                       progress_for=progress)
    if not State.quiet:
        out_console.print(claims_table(claims, "paper 000: the paper's claims"))
        say(f"wrote figures, tables and claims.json to {out}")


@paper_app.command("002")
@one_line_errors
def paper_002(
    out: Annotated[Path, typer.Option(help="Directory for the measurement, the reprocessing "
                                           "results, figures and claims.json.")],
    seed: Annotated[int, typer.Option(min=0, help="Seed of the manufactured universe (the "
                                                  "variations use seed + 1).")] = 0,
    variations: Annotated[int, typer.Option(help="Variations of the cut-in (sec. V).")] = 300,
    workers: Workers = None,
    scheduler: Scheduler = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
) -> None:
    """Wagner, Groh et al.: reprocessing the cut-in (Figs. 3-8, eqs. 2-7) and its claims."""
    from simcred.paper import reprocessing

    check_count(variations, "variations", "--variations (for the 5th/95th percentiles)",
                minimum=20)
    with writing(out, overwrite=overwrite, resume=resume) as target, \
            target.engine(workers, scheduler) as runner:
        run = reprocessing.run_all(target.path, seed=seed, variations=variations,
                                   runner=runner, progress_for=progress)
    if not State.quiet:
        out_console.print(claims_table(run.claims, "paper 002: the paper's claims"))
        say(run.reaction_summary())
        say(f"wrote measurement, results, figures and claims.json to {out}")



@paper_app.command("all")
@one_line_errors
def paper_all(
    out: Annotated[Path, typer.Option(help="Directory for every paper's results and the "
                                           "combined claims.json.")],
    runs: Annotated[int | None, typer.Option(help="Paper 000: runs per trace set (default: the "
                                                  "documented full size).")] = None,
    variations: Annotated[int, typer.Option(help="Paper 002: variations of the cut-in.")] = 300,
    seed: Annotated[int, typer.Option(min=0, help="Seed of every experiment.")] = 0,
    workers: Workers = None,
    scheduler: Scheduler = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
) -> None:
    """All three papers: 000, 002, and paper 003's contracts on the cut-in."""
    from simcred.paper.all import AllOptions, run_all

    if runs is not None:
        check_count(runs, "runs", "--runs", minimum=2)
    check_count(variations, "variations", "--variations", minimum=20)
    with writing(out, overwrite=overwrite, resume=resume) as target, \
            target.engine(workers, scheduler) as runner:
        claims = run_all(target.path, AllOptions(runs=runs, variations=variations, seed=seed),
                         runner=runner, progress_for=progress)
    if not State.quiet:
        for key, found in claims.items():
            out_console.print(claims_table(found, f"seed {key}: claims"))
        total = sum(len(c) for c in claims.values())
        held = sum(c.passed for found in claims.values() for c in found)
        say(f"{held} of {total} claims hold; wrote {out / 'claims.json'}")


@app.command()
@one_line_errors
def report(
    directory: Annotated[Path, typer.Argument(metavar="DIR", help="Output directory of simcred "
                                                                  "paper all.")],
    out: Annotated[Path | None, typer.Option(help="HTML file to write (default: "
                                                  "DIR/index.html).")] = None,
    overwrite: Overwrite = False,
) -> None:
    """Write a self-contained HTML report of the papers' claims, figures and provenance."""
    from simcred.report.html import write_report

    if out is not None:  # the default DIR/index.html is the report's own place: replaced
        check_output(out, directory, kind="file", overwrite=overwrite)
    path = write_report(directory, out=out)  # atomically: complete or not at all
    if not State.quiet:
        say(str(path))




def claims_table(claims, title: str):
    """The claims as a table: id, claim, value, bound, passed (green yes / red no)."""
    from rich.text import Text

    def row(c):
        value = "—" if c.value is None else f"{c.value:.4g}"
        bound = "—" if c.bound is None else f"{c.bound:.4g}"
        verdict = Text("yes", style="green") if c.passed else Text("no", style="red")
        return c.id, c.claim, value, bound, verdict

    return plain_table(title, ("id", "claim", "value", "bound", "passed"), map(row, claims))
