"""SUMO as a real third-party simulator: replay recorded leaders, let SUMO's car-following models
drive the followers.

For every episode of a car-following :class:`~simcred.traces.TraceSet` (signals ``gap`` [m], ``v``
[m/s] follower speed and ``v_leader`` [m/s], uniform time step) one SUMO simulation runs in-process
through ``libsumo``:

* the network is one straight single-lane road (20 km, speed limit :data:`ROAD_SPEED` m/s), so
  there are no junctions and no lane changes (lane-change mode 0 as well);
* step length = the episode's time step; ``--seed`` = a 31-bit integer from
  ``SeedSequence(seed, spawn_key=(h,))`` with ``h`` a hash of the run id, so an episode gets the
  same SUMO seed whatever set or chunk it is simulated in;
* at the first step both cars are inserted at once (``insertionChecks="none"``): the follower's
  front at 10 m with the recorded speed, the leader's rear at the recorded gap ahead with the
  recorded leader speed;
* from then on the leader's recorded speed is imposed before every step (``setSpeed`` with speed
  mode 0: no safe-speed, acceleration or deceleration limits), so after step ``k`` its speed is
  the recorded ``v_leader[k]`` exactly; the follower is driven by the chosen model;
* outputs are read with ``libsumo`` at full double precision after every step: gap = leader rear −
  follower front, ``dv`` = leader − follower speed, ``a`` = central difference of the follower's
  speed (the same derivation as :func:`simcred.io.openacc.acceleration` for the real data).

Vehicle types use SUMO's defaults for a passenger car, except ``speedDev=0`` (every follower
wants the road's speed limit) and the length (4.5 m, irrelevant for bumper-to-bumper gaps);
:class:`SumoModel` adds any vType attribute (``tau``, ``accel``, ``sigma``...). Collisions are not
resolved by SUMO (``--collision.action none``): a negative gap stays in the output and is counted.
"""

from __future__ import annotations

import atexit
import functools
import os
import shutil
import subprocess
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from xml.sax.saxutils import quoteattr

import numpy as np

from simcred.engine import Engine, Progress, engine
from simcred.errors import MissingDependencyError, OptionError, TraceSetError
from simcred.limits import check_count
from simcred.seeds import sumo_episode_seed
from simcred.traces import RUN_INFO, TIME, TraceSet, concat, take

REQUIRED = ("gap", "v", "v_leader")
SIGNALS = ("gap", "dv", "v", "a", "v_leader")
#: Car-following models of SUMO that :class:`SumoModel` accepts (``carFollowModel`` values).
#: SUMO's car-following models (its ``carFollowModel`` names) simcred replays with; "IIDM" was
#: listed once, but SUMO has no such model (libsumo: "Unknown car following model 'IIDM'").
MODELS = ("Krauss", "IDM", "EIDM", "ACC", "CACC", "KraussPS", "Wiedemann", "W99")
ROAD_LENGTH = 20_000.0  # m
ROAD_SPEED = 36.11  # m/s (130 km/h): speed limit of the road, the followers' desired speed
FOLLOWER_START = 10.0  # m, lane position of the follower's front at the start
LENGTH = 4.5  # m, both cars
STEP_TOLERANCE = 1e-6  # s: every time step of an episode must equal the first within this
INSTALL_SUMO = "eclipse-sumo libsumo"  # the pip packages of SUMO (pyproject.toml names them)
_NAME_CHARS = set("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-")


@dataclass(frozen=True, slots=True)
class SumoModel:
    """A SUMO car-following model for the follower: ``carFollowModel`` plus vType attributes.

    Parameters
    ----------
    model : str
        One of :data:`MODELS` (SUMO's ``carFollowModel`` attribute), e.g. "Krauss", "IDM", "EIDM",
        "ACC".
    params : mapping of str to float, optional
        Further vType attributes, e.g. ``{"tau": 1.2, "sigma": 0.0}``; SUMO's defaults otherwise.
    name : str, optional
        Label in outputs (default: ``model``).
    """

    model: str
    params: Mapping[str, float] = field(default_factory=dict)
    name: str = ""

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise OptionError(f"SUMO car-following model must be one of {', '.join(MODELS)}; "
                              f"got {self.model!r}")
        params = dict(self.params)
        for key, value in params.items():
            if not key or not set(key) <= _NAME_CHARS or key in ("id", "carFollowModel"):
                raise OptionError(f"SUMO vType attribute {key!r} is not allowed")
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not np.isfinite(value):
                raise OptionError(f"SUMO vType attribute {key}={value!r} must be a finite number")
        object.__setattr__(self, "params", dict(sorted(params.items())))
        object.__setattr__(self, "name", self.name or self.model)

    def vtype(self, type_id: str) -> str:
        attrs = {"carFollowModel": self.model, "length": LENGTH, "speedDev": 0,
                 **self.params}
        text = " ".join(f"{k}={quoteattr(_number(v))}" for k, v in attrs.items())
        return f'<vType id="{type_id}" {text}/>'

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "model": self.model, "params": dict(self.params)}


def _number(value: Any) -> str:
    return value if isinstance(value, str) else repr(float(value)) if isinstance(value, float) \
        else str(value)


def parse_model(text: str) -> SumoModel:
    """``"IDM"`` or ``"IDM:tau=1.2,accel=1.5"`` (attributes after a colon) → :class:`SumoModel`."""
    name, _, rest = text.strip().partition(":")
    params = {}
    for item in filter(None, (p.strip() for p in rest.split(","))):
        key, eq, value = item.partition("=")
        try:
            params[key.strip()] = float(value)
        except ValueError:
            raise OptionError(f"SUMO model {text!r}: attribute {item!r} must be NAME=NUMBER"
                              ) from None
        if not eq:
            raise OptionError(f"SUMO model {text!r}: attribute {item!r} must be NAME=NUMBER")
    label = name.strip() if not params else text.strip()
    return SumoModel(name.strip(), params, label)


# -- one process's SUMO ---------------------------------------------------------------------------

def _libsumo():
    """libsumo, imported without its stdout notice about the pyarrow version it was built with
    (simcred uses none of SUMO's file outputs, and replays followed by Parquet writing in one
    process are tested). LIBSUMO_AS_TRACI=quiet would also silence it, but that variable makes
    every later ``import traci`` load libsumo instead."""
    import contextlib
    import io

    try:
        with contextlib.redirect_stdout(io.StringIO()):
            import libsumo
    except (ImportError, OSError) as exc:
        raise MissingDependencyError(
            f"SUMO is not installed: libsumo cannot be imported ({exc}); install it with "
            f"'pip install {INSTALL_SUMO}'") from None
    return libsumo


def require_sumo() -> None:
    """Raise :class:`~simcred.errors.MissingDependencyError` (one line: what is missing, how to
    install it) unless libsumo and netconvert are both there; replays check before they start."""
    _libsumo()
    _netconvert()


def sumo_version() -> str:
    """The version of the SUMO that runs the replays (libsumo's)."""
    return str(_libsumo().__version__)


def _network() -> Path:
    """The straight road, built once per process with SUMO's netconvert into a temporary folder
    (built again if something removed it)."""
    net = _network_folder() / "road.net.xml"
    if not net.is_file():
        _network_folder.cache_clear()
        net = _network_folder() / "road.net.xml"
    return net


@functools.cache
def _network_folder() -> Path:
    """A new temporary folder (removed at exit) holding the road built by netconvert."""
    folder = Path(tempfile.mkdtemp(prefix="simcred-sumo-"))
    atexit.register(shutil.rmtree, folder, True)
    (folder / "road.nod.xml").write_text(
        f'<nodes><node id="a" x="0" y="0"/><node id="b" x="{ROAD_LENGTH}" y="0"/></nodes>')
    (folder / "road.edg.xml").write_text(
        f'<edges><edge id="road" from="a" to="b" numLanes="1" speed="{ROAD_SPEED}"/></edges>')
    done = subprocess.run([_netconvert(), "-n", "road.nod.xml", "-e", "road.edg.xml",
                           "-o", "road.net.xml", "--no-turnarounds", "true"],
                          cwd=folder, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"netconvert failed: {done.stderr.strip()}")
    return folder


def _netconvert() -> str:
    """SUMO's netconvert from the eclipse-sumo wheel (found through its metadata, not by importing
    a module named ``sumo``, which a script of that name would shadow), else from PATH."""
    from importlib.metadata import PackageNotFoundError, distribution

    try:
        path = Path(str(distribution("eclipse-sumo").locate_file("sumo/bin/netconvert")))
        if path.is_file():
            return str(path)
    except PackageNotFoundError:
        pass
    found = shutil.which("netconvert")
    if found is None:
        raise MissingDependencyError(
            "SUMO's netconvert is not installed: neither the eclipse-sumo package nor PATH has "
            f"it; install it with 'pip install {INSTALL_SUMO}' (or put SUMO's bin/ on PATH)")
    return found


def episode_seed(seed: int, run_id: str) -> int:
    """SUMO's ``--seed`` for the episode ``run_id``: 31 bits of ``SeedSequence(seed, (hash,))``
    (:func:`simcred.seeds.sumo_episode_seed`)."""
    return sumo_episode_seed(seed, run_id)


@dataclass(frozen=True, slots=True)
class _Episode:
    run_id: str
    time: np.ndarray
    gap: np.ndarray
    v: np.ndarray
    v_leader: np.ndarray

    @property
    def step(self) -> float:
        return float(self.time[1] - self.time[0])


def _routes(model: SumoModel, ep: _Episode) -> str:
    leader_front = float(FOLLOWER_START + ep.gap[0] + LENGTH)
    return (
        "<routes>\n"
        f'<vType id="leader" length="{LENGTH}" speedDev="0" maxSpeed="100" accel="100" '
        'decel="100" emergencyDecel="100" sigma="0"/>\n'
        f"{model.vtype('follower')}\n"
        '<route id="r" edges="road"/>\n'
        f'<vehicle id="L" type="leader" route="r" depart="0" departPos="{leader_front!r}" '
        f'departSpeed="{float(ep.v_leader[0])!r}" insertionChecks="none"/>\n'
        f'<vehicle id="F" type="follower" route="r" depart="0" departPos="{FOLLOWER_START!r}" '
        f'departSpeed="{float(ep.v[0])!r}" insertionChecks="none"/>\n'
        "</routes>\n"
    )


def _options(net: Path, routes: Path, step: float, seed: int) -> list[str]:
    return ["-n", str(net), "-r", str(routes), "--step-length", repr(step), "--seed", str(seed),
            "--begin", "0", "--no-step-log", "true", "--no-warnings", "true",
            "--collision.action", "none", "--duration-log.disable", "true"]


def _replay(sumo, model: SumoModel, ep: _Episode, seed: int, started: bool) -> np.ndarray:
    """One SUMO run; returns ``(steps, 4)``: leader position, leader speed, follower position,
    follower speed (front bumpers, lane coordinates [m], speeds [m/s])."""
    net = _network()
    routes = net.parent / f"routes-{os.getpid()}.rou.xml"
    routes.write_text(_routes(model, ep))
    options = _options(net, routes, ep.step, seed)
    if started:
        sumo.load(options)
    else:
        sumo.start(["sumo", *options])
    vehicle = sumo.vehicle
    out = np.empty((len(ep.time), 4))
    sumo.simulationStep()  # both cars inserted at their recorded state
    vehicle.setSpeedMode("L", 0)
    vehicle.setLaneChangeMode("L", 0)
    vehicle.setLaneChangeMode("F", 0)
    for k in range(len(ep.time)):
        if k:
            vehicle.setSpeed("L", float(ep.v_leader[k]))
            sumo.simulationStep()
        out[k] = (vehicle.getLanePosition("L"), vehicle.getSpeed("L"),
                  vehicle.getLanePosition("F"), vehicle.getSpeed("F"))
    return out


def _signals(ep: _Episode, raw: np.ndarray) -> dict[str, np.ndarray]:
    from simcred.io.openacc import acceleration

    gap = raw[:, 0] - LENGTH - raw[:, 2]
    return {TIME: ep.time, "gap": gap, "dv": raw[:, 1] - raw[:, 3], "v": raw[:, 3],
            "a": acceleration(raw[:, 3], ep.step), "v_leader": raw[:, 1]}


def _simulate_chunk(task: tuple[SumoModel, int, Sequence[int], TraceSet]) -> TraceSet:
    """Replays of the episodes ``indices`` of the input, given as ``chunk`` (those runs only)."""
    model, seed, indices, traces = task
    sumo = _libsumo()
    runs, ids, info = [], [], {}
    try:
        for n in range(len(indices)):
            ep = _episode(traces, n)
            sumo_seed = episode_seed(seed, ep.run_id)
            runs.append(_signals(ep, _replay(sumo, model, ep, sumo_seed, started=n > 0)))
            ids.append(ep.run_id)
            info[ep.run_id] = {**_input_info(traces, ep.run_id), "sumo_seed": sumo_seed}
    finally:
        sumo.close()
    return TraceSet.from_runs(runs, run_ids=ids, metadata={RUN_INFO: info},
                              source=f"sumo:{model.name}")


def _input_info(traces: TraceSet, run_id: str) -> dict[str, Any]:
    info = traces.metadata.get(RUN_INFO)
    return dict(info.get(run_id, {})) if isinstance(info, Mapping) else {}


def _episode(traces: TraceSet, i: int) -> _Episode:
    run = traces.run(i)
    return _Episode(traces.run_ids[i], np.asarray(run[TIME]), *(np.asarray(run[s]) for s in
                                                               REQUIRED))


def _validate(traces: TraceSet) -> None:
    for name in REQUIRED:
        traces.column(name)  # raises naming the set and the missing signal
    for i in range(traces.n_runs):
        run = traces.run(i)
        dt = np.diff(run[TIME])
        where = f"{traces.source}: run '{traces.run_ids[i]}'"
        if not np.all(np.abs(dt - dt[0]) <= STEP_TOLERANCE):
            raise TraceSetError(f"{where}: time steps are not uniform (SUMO needs one step "
                                f"length; steps range {dt.min()}–{dt.max()} s)")
        if run["gap"][0] < 0 or np.any(run["v"] < 0) or np.any(run["v_leader"] < 0):
            raise TraceSetError(f"{where}: negative start gap or speed")
        travel = FOLLOWER_START + run["gap"][0] + LENGTH + float(np.sum(run["v_leader"])) * dt[0]
        if travel > ROAD_LENGTH - 100:
            raise TraceSetError(f"{where}: the leader would drive {travel:.0f} m, beyond the "
                                f"{ROAD_LENGTH:.0f} m road; cut shorter episodes")


@dataclass(frozen=True, slots=True, eq=False)
class Replay:
    """Seeded SUMO replays of the recorded leaders of ``traces`` with ``model`` as the follower."""

    traces: TraceSet
    model: SumoModel
    seed: int
    chunk_size: int = 50

    def __post_init__(self) -> None:
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise OptionError(f"seed must be a non-negative integer, got {self.seed!r}")
        check_count(self.chunk_size, "runs", "chunk size")
        check_count(self.traces.n_runs, "runs", "episodes to replay")
        _validate(self.traces)

    def tasks(self) -> list[tuple[SumoModel, int, range]]:
        n = self.traces.n_runs
        return [(self.model, self.seed, range(lo, min(lo + self.chunk_size, n)))
                for lo in range(0, n, self.chunk_size)]

    def metadata(self) -> dict[str, Any]:
        return {"simulator": "SUMO", "sumo_version": sumo_version(), "model": self.model.to_dict(),
                "seed": self.seed, "input": {"source": self.traces.source,
                                             "digest": self.traces.digest()},
                "road": {"length_m": ROAD_LENGTH, "speed_limit_mps": ROAD_SPEED, "lanes": 1},
                "units": {"gap": "m", "dv": "m/s", "v": "m/s", "a": "m/s²", "v_leader": "m/s",
                          TIME: "s"}}


def replay(traces: TraceSet, models: Sequence[SumoModel | str], *, seed: int = 0,
           workers: int | None = None, scheduler: str | None = None,
           runner: Engine | None = None, chunk_size: int = 50,
           progress: Progress | None = None) -> dict[str, TraceSet]:
    """Replay every episode of ``traces`` with each SUMO model (see the module doc).

    Parameters
    ----------
    traces : TraceSet
        Car-following episodes with signals ``gap``, ``v``, ``v_leader`` and a uniform step.
    models : sequence of SumoModel or str
        Follower models; strings as :func:`parse_model` reads them ("IDM", "IDM:tau=1.2").
    seed : int, default: 0
        Campaign seed; episode ``r`` runs with SUMO ``--seed`` :func:`episode_seed` (seed, r).
    workers, scheduler, runner
        In-process (default), on a local Dask cluster, on a scheduler, or on a started engine.
    chunk_size : int, default: 50
        Episodes per task (one SUMO process state per task).

    Returns
    -------
    dict of str to TraceSet
        Per model name, a set with the same run ids and time stamps as ``traces`` and signals
        :data:`SIGNALS`; metadata: simulator, versions, model, seed, input digest, per-run
        ``run_info`` (the input's, plus ``sumo_seed``) and the number of runs with a negative gap.
        The same inputs and seed give identical sets, serially or on Dask.
    """
    specs = [m if isinstance(m, SumoModel) else parse_model(m) for m in models]
    if not specs:
        raise OptionError("give at least one SUMO model")
    names = [m.name for m in specs]
    if len(set(names)) != len(names):
        raise OptionError(f"SUMO model names repeat: {names}")
    plans = [Replay(traces, m, seed, chunk_size) for m in specs]
    require_sumo()  # one line now, not a failed task on a worker
    if runner is None:
        with engine(workers, scheduler) as started:
            return replay(traces, specs, seed=seed, runner=started, chunk_size=chunk_size,
                          progress=progress)
    # each chunk's episodes travel once, to one worker, not the whole input to every worker
    chunks = runner.put([take(traces, indices) for _, _, indices in plans[0].tasks()])
    tasks = [(*task, chunk) for plan in plans for task, chunk in zip(plan.tasks(), chunks,
                                                                      strict=True)]
    parts = runner.map(_simulate_chunk, tasks, progress=progress)
    out, k = {}, 0
    for plan in plans:
        mine = parts[k:k + len(plan.tasks())]
        k += len(mine)
        joined = concat(mine, source=f"sumo:{plan.model.name}")
        info = {r: v for p in mine for r, v in p.metadata[RUN_INFO].items()}
        collided = sum(1 for i in range(joined.n_runs) if joined.run(i)["gap"].min() < 0)
        metadata = {**plan.metadata(), "negative_gap_runs": collided, RUN_INFO: info}
        out[plan.model.name] = TraceSet(joined.signals, joined.time, joined.values,
                                        joined.offsets, joined.run_ids, metadata, joined.source)
    return out


def write_replays(results: Mapping[str, TraceSet], out: str | Path, *,
                  options: Mapping[str, Any]) -> list[Path]:
    """``<out>/<model>.parquet`` per model and ``<out>/sumo-following.json`` (provenance)."""
    from simcred._json import dumps, envelope

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths, models = [], []
    for name, traces in results.items():
        safe = "".join(c if c in _NAME_CHARS else "_" for c in name)
        paths.append(traces.write(out / f"{safe}.parquet"))
        meta = traces.metadata
        models.append({"name": name, "file": paths[-1].name, "digest": traces.digest(),
                       "runs": traces.n_runs, "model": meta["model"],
                       "negative_gap_runs": meta["negative_gap_runs"]})
    first = next(iter(results.values())).metadata
    from simcred._version import versions

    body = {"simulator": "SUMO", "sumo_version": first["sumo_version"],
            "versions": versions("numpy", sumo=first["sumo_version"]),
            "input": first["input"], "options": dict(options), "road": first["road"],
            "units": first["units"], "models": models}
    (out / "sumo-following.json").write_text(dumps(envelope("sumo_following", body)))
    return [*paths, out / "sumo-following.json"]
