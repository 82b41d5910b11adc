"""The simulators of ``simcred simulate NAME``, by name: one place that checks each one's
parameters and builds and writes its runs.

The command line (:mod:`simcred.cli.simulate`) and ``validate`` (a candidate's ``simulate``
command, :mod:`simcred.validate.simulate`) both run a simulator through :data:`SIMULATORS`, so
``validate`` runs a validation file's simulator as a library call: no re-entry into the CLI, no
global state. This module is the one outside ``paper`` and ``cli`` that names the experiments
(docs/architecture.md).

>>> sorted(SIMULATORS)
['cutin', 'simplecar', 'sumo-following', 'tjunction']
>>> SIMULATORS["simplecar"].parse(["--runs", "2", "--lambda=0.5"])["lam"]
0.5
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

from simcred.engine import Engine, Progress, engine
from simcred.errors import OptionError
from simcred.limits import check_count, check_finite
from simcred.outputs import output_path


@dataclass(frozen=True, slots=True)
class Param:
    """A parameter of a simulator: its keyword, how its command-line text is read, its default,
    its option (``--name-with-dashes``, or ``flag``; ``positional`` for an argument) and whether
    it is a path the simulator reads (its output may not be, contain or lie inside it)."""

    name: str
    parse: Callable[[str], Any]
    default: Any = None
    flag: str | None = None
    positional: bool = False
    reads: bool = False

    @property
    def option(self) -> str:
        return self.flag or "--" + self.name.replace("_", "-")


#: Where a campaign's chunks run: taken by every simulator that uses a runner.
RUNNER_PARAMS = (Param("workers", int), Param("scheduler", str))


@dataclass(frozen=True, slots=True)
class Simulator:
    """One simulator: ``check(params)`` (one-line :class:`~simcred.errors.OptionError` before
    anything is written) and ``write(path, params, runner, progress)``, which writes the runs
    at ``path`` and returns what it wrote in words. ``trace_set``: the output is one trace set
    whose suffix picks its format (else a directory); ``runner``: chunks run on an
    :class:`~simcred.engine.Engine`; ``slash``: the output named as a folder in the summary."""

    name: str
    params: tuple[Param, ...]
    check: Callable[[dict[str, Any]], None]
    write: Callable[[Path, dict[str, Any], Engine | None, Progress | None], str]
    progress: str = ""
    trace_set: bool = False
    runner: bool = True
    slash: bool = False
    resumable: bool = True
    all_params: tuple[Param, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "all_params",
                           self.params + (RUNNER_PARAMS if self.runner else ()))

    def defaults(self, **given: Any) -> dict[str, Any]:
        """Every parameter: ``given`` over the defaults (one line for an unknown keyword)."""
        names = [p.name for p in self.all_params]
        unknown = [k for k in given if k not in names]
        if unknown:
            raise OptionError(f"simulate {self.name}: no parameter {unknown[0]!r} "
                              f"(parameters: {', '.join(names)})")
        return {p.name: given.get(p.name, p.default) for p in self.all_params}

    def parse(self, args: Sequence[str]) -> dict[str, Any]:
        """The parameters of a command line (``--option value``, ``--option=value``,
        arguments in order), defaults for the others; one line for what it cannot read."""
        by_option = {p.option: p for p in self.all_params if not p.positional}
        positional = [p for p in self.all_params if p.positional]
        given: dict[str, Any] = {}
        items = iter(args)
        for arg in items:
            option, eq, text = arg.partition("=")
            if arg.startswith("-") and option in by_option:
                param = by_option[option]
                text = text if eq else next(items, None)
                if text is None:
                    raise OptionError(f"simulate {self.name}: {option} needs a value")
            elif arg.startswith("-"):
                raise OptionError(f"simulate {self.name}: no option {option} (options: "
                                  f"{', '.join(by_option)})")
            elif positional:
                param, text = positional.pop(0), arg
            else:
                raise OptionError(f"simulate {self.name}: unexpected argument {arg!r}")
            given[param.name] = _read(param, text, self.name)
        if positional:
            raise OptionError(f"simulate {self.name}: missing argument "
                              f"{positional[0].name.upper()}")
        return self.defaults(**given)

    def inputs(self, params: Mapping[str, Any]) -> list[Path]:
        """The paths the simulator reads."""
        return [Path(params[p.name]) for p in self.params if p.reads]


def _read(param: Param, text: str, simulator: str) -> Any:
    try:
        return param.parse(text)
    except ValueError:
        raise OptionError(f"simulate {simulator}: {param.option}: cannot read {text!r} as "
                          f"{getattr(param.parse, '__name__', 'a value')}") from None


def run(args: Sequence[str], out: Path, *, progress: Progress | None = None) -> str:
    """Run the command line ``args`` (``simulate NAME ...``, without ``--out``) into the new
    directory ``out`` (written atomically: ``OUT.partial``, renamed when complete); what it
    wrote, in words."""
    if len(args) < 2 or args[0] != "simulate":
        raise OptionError(f"a simulator command is 'simulate NAME ...', got {list(args)!r}")
    simulator = SIMULATORS.get(args[1])
    if simulator is None:
        raise OptionError(f"no simulator {args[1]!r} (simulators: {', '.join(SIMULATORS)})")
    params = simulator.parse(args[2:])
    simulator.check(params)
    with output_path(out, simulator.inputs(params)) as path:
        if not simulator.runner:
            return simulator.write(path, params, None, progress)
        with engine(params["workers"], params["scheduler"]) as runner:
            return simulator.write(path, params, runner, progress)


# -- the simulators -----------------------------------------------------------------------------


def _check_simplecar(params: dict[str, Any]) -> None:
    check_finite(params["lam"], "--lambda", minimum=0.01, open_minimum=True, maximum=100)
    check_finite(params["dt"], "--dt", minimum=0, open_minimum=True)
    check_finite(params["duration"], "--duration", minimum=0, open_minimum=True)
    steps = check_count(round(params["duration"] / params["dt"]) + 1, "steps",
                        "--duration / --dt + 1")
    check_count(check_count(params["runs"], "runs", "--runs") * steps, "rows", "--runs × steps")


def _campaign(simulate: Callable, keys: Sequence[str]) -> Callable:
    def write(path: Path, params: dict[str, Any], runner: Engine | None,
              progress: Progress | None) -> str:
        from simcred.sim.campaign import Campaign

        campaign = Campaign(simulate, params["runs"], params["seed"],
                            {k: params[k] for k in keys}, params["chunk_size"])
        traces = campaign.run(runner=runner, progress=progress)
        traces.write(path)
        return (f"{traces.n_runs} runs, {traces.n_rows} rows, signals "
                f"{', '.join(traces.signals)}")
    return write


def _simplecar(path: Path, params: dict[str, Any], runner: Engine | None,
               progress: Progress | None) -> str:
    from simcred.sim.experiments import simplecar_sweep

    return _campaign(simplecar_sweep.simulate, ("lam", "dt", "duration"))(
        path, params, runner, progress)


def _check_tjunction(params: dict[str, Any]) -> None:
    from simcred.sim.experiments import tjunction

    if params["category"] not in tjunction.CATEGORIES:
        raise OptionError(f"category must be one of {', '.join(tjunction.CATEGORIES)}; "
                          f"got {params['category']!r}")


def _tjunction(path: Path, params: dict[str, Any], runner: Engine | None,
               progress: Progress | None) -> str:
    from simcred.sim.experiments import tjunction

    return _campaign(tjunction.simulate, ("category",))(path, params, runner, progress)


def _cutin(path: Path, params: dict[str, Any], runner: Engine | None,
           progress: Progress | None) -> str:
    from simcred.sim.experiments import cutin

    measurement = cutin.simulate(params["seed"], cutin.CutInConfig(ego_model=params["ego_model"]))
    measurement.write(path)
    return f"GT and SD, {measurement.sd.n_rows} samples each"


def sumo_models(text: str) -> list[str]:
    """``IDM:tau=1.2+accel=1.5,Krauss`` → the models with their vType attributes."""
    return [part.strip().replace("+", ",") for part in text.split(",") if part.strip()]


def _sumo_following(path: Path, params: dict[str, Any], runner: Engine | None,
                    progress: Progress | None) -> str:
    from simcred.sim.sumo import replay, write_replays
    from simcred.traces import TraceSet

    source = TraceSet.read(params["traces"])
    results = replay(source, sumo_models(params["models"]), seed=params["seed"], runner=runner,
                     chunk_size=params["chunk_size"], progress=progress)
    written = write_replays(results, path, options={
        "models": params["models"], "seed": params["seed"], "chunk_size": params["chunk_size"]})
    return (f"{', '.join(p.name for p in written)}: {source.n_runs} episodes x "
            f"{len(results)} models")


def _nothing(params: dict[str, Any]) -> None:
    """No check beyond reading the parameters."""


SEED = Param("seed", int, 0)
SIMULATORS: Mapping[str, Simulator] = MappingProxyType({
    "simplecar": Simulator(
        "simplecar", (Param("lam", float, 1.0, flag="--lambda"), Param("runs", int, 1000), SEED,
                      Param("dt", float, 2.0), Param("duration", float, 40.0),
                      Param("chunk_size", int, 250)),
        _check_simplecar, _simplecar, "simulating chunks", trace_set=True),
    "tjunction": Simulator(
        "tjunction", (Param("category", str, "no-occlusion"), Param("runs", int, 1000), SEED,
                      Param("chunk_size", int, 250)),
        _check_tjunction, _tjunction,
        "simulating chunks", trace_set=True),
    "cutin": Simulator(
        "cutin", (SEED, Param("ego_model", str, "st")), _nothing, _cutin, runner=False,
        resumable=False),
    "sumo-following": Simulator(
        "sumo-following", (Param("traces", Path, positional=True, reads=True),
                           Param("models", str, "Krauss,IDM,EIDM"), SEED,
                           Param("chunk_size", int, 50)),
        _nothing, _sumo_following, "SUMO episodes (chunks)", slash=True),
})

__all__ = ["SIMULATORS", "Param", "Simulator", "run", "sumo_models"]
