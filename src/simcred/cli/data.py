"""simcred data: the real data shipped with simcred (OpenACC, the A9 recording)."""

from __future__ import annotations

from typing import Annotated

import typer

from simcred.cli._app import app, one_line_errors, out_console

data_app = typer.Typer(help="Real data shipped with simcred (with licences and attribution).")
app.add_typer(data_app, name="data")


@data_app.command("path")
@one_line_errors
def data_path(
    name: Annotated[str, typer.Argument(help="A shipped file or folder, e.g. "
                                             "a9/trajectories_file.csv or openacc.")],
) -> None:
    """Print the path of a shipped data file or folder."""
    from simcred import data

    out_console.print(str(data.path(name)), highlight=False, soft_wrap=True)


@data_app.command("list")
def data_list() -> None:
    """List every shipped data file."""
    from simcred import data

    for name in data.names():
        out_console.print(name, highlight=False)
