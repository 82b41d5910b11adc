"""Known-truth designs for ``simcred validate`` (issue 22): what the verdict must say is known.

* :func:`closed_loop_pair` — the human-like IDM of :mod:`response_designs` (same parameters,
  same per-run headway trait, same AR(1) noise law) behind recorded OpenACC leader windows,
  simulated at ``DT = 0.1 s`` (the recordings' own step); the candidate replays THE SAME windows
  from the same start states with its own noise and trait draws and one defect (:data:`DEFECTS`):
  ``none`` (truth: valid), a reaction delay of 0.15 / 0.3 / 0.5 / 1.0 s or clipped acceleration
  (truth: not valid; ``delay_0.15`` is the study's tolerance, see scripts/validate_truth.py).
* :func:`human_halves` — real OpenACC human-follower episodes split into two random halves by
  *unit* (one follower in one recording, see below): the same population on both sides (truth:
  valid).

Why not ``response_designs.simulate``: it runs at the module constant ``DT = 0.5 s`` (its delay
is a whole number of those steps, its windows are thinned to 0.5 s and ``to_traceset`` writes
the 0.5 s clock). A delay of 0.15 / 0.3 s needs a finer step, so :func:`simulate` here is the
same closed loop (same IDM via :func:`response_designs.idm`, same ballistic update with the
leader speed held over the step, same limits) with the step as an argument and a delay in
seconds (fractional steps: the delayed state is interpolated linearly between two steps).

Noise at 0.1 s. ``response_designs.HUMAN`` has AR(1) noise with stationary sd 0.2 m/s² and
``phi = 0.9`` per 0.5 s step: correlation time ``tau = -0.5 / ln 0.9 = 4.75 s``. Here
``phi = 0.9 ** (0.1 / 0.5) = 0.9791`` per 0.1 s step (:data:`PHI`), sd 0.2 m/s², innovations
``0.2 sqrt(1 - phi²)``: the same stationary sd and correlation time, started stationary.

Leader windows. A window is ``seconds`` (default :data:`WINDOW` = 25 s, 251 samples) of one
OpenACC track (chained consecutive episodes of one leader–follower pair at 0.1 s,
:func:`response_designs.tracks`), any start sample, distinct windows within a draw. 25 s: several
leader manoeuvres per run, much longer than the longest delay (1 s) and than the IDM's relaxation
after the start (a few seconds), and 39 of the 50 tracks hold one (50,244 windows). The recorded
leader speeds lie in 0–20.6 m/s (69 % below 15 m/s), so by default (``shift=True``) each window's
profile is shifted by a per-window offset drawn uniformly in the range that keeps the whole window
in [0, :data:`V_MAX`] m/s: the recorded dynamics (accelerations, stop-and-go shapes) are kept,
the speeds span 0–28 m/s, and both cells of the study's grid (v_leader < 15, ≥ 15) get data.
V_MAX = 28 m/s, not 30: near the IDM's desired speed v0 = 30 m/s the free-road term takes over
and the follower falls back (equilibrium gap 90 m at 28 m/s, 180 m at 29.5 m/s).

Start states. Both sides start at the IDM equilibrium gap of the NOMINAL headway T = 1.5 s at the
leader's first speed, dv = 0 (not at a run's own T): the reference and the candidate of a pair
then start from the same state and neither sits at its own equilibrium, so with ``defect="none"``
the pair is exchangeable in law (an exact same-law design, truth deviation 0).

Defects of the candidate (the IDM command, applied acceleration = command + noise):

* ``delay_X``: the command is computed from the state (gap, v, v_leader) X seconds ago (state at
  the start before t = 0); the noise is not delayed;
* ``clip``: the applied acceleration (command + noise) clipped to [-1.5, +0.5] m/s²
  (:data:`CLIP`): +0.5 is the reference's 97.5 % quantile of applied acceleration, -1.5 about
  its 0.04 % quantile (its 0.1 % quantile is -1.27). The brief's ±0.5 m/s² (``clip_0.5``, a
  diagnostic, not in :data:`DEFECTS`) makes runs crash: 1.2-1.5 % of them end with gap < 0
  (down to -40 m; the clipped brake cannot follow a leader that slows to a stop), with or
  without the speed shift. Lower bounds measured on 5 × 8,000 runs: -1.0 crashes 2-7 runs in
  8,000; -1.25 none, but 1 in 8,000 comes within 0.2 m; -1.5 keeps every run's gap >= 1.7 m,
  as the reference's (the candidate sits at -1.5 in 0.05 % of its samples). A symmetric clip
  that does not crash (±1.25) changes 0.3 % of samples and deviates less than the 0.15 s
  delay, so the defect is asymmetric: a sluggish accelerator (3.3 % of samples at +0.5) whose
  brake is limited only where the reference itself almost never brakes.

Signals and units as :func:`response_designs.to_traceset` (``gap`` [m], ``dv`` = v_leader − v
[m/s], ``v`` [m/s], ``a`` [m/s²] applied acceleration over [t, t + dt), ``v_leader`` [m/s]),
``metadata["units"]`` and per-run facts ``metadata["run_info"]`` (``file``, ``leader_vehicle``,
``follower_vehicle``, ``track``, ``start_sample``, ``offset``, ``T``, ``defect``).

Human halves: the unit. The 609 episodes (10 s at 0.1 s) come from 24 (recording, follower
position) pairs: one human driver following one car in one recording, 20–30 consecutive episodes
each (their clocks 10.1 s apart: one drive, the same driver's habits, the same leader's
manoeuvres). Episodes of one unit are dependent, so a unit stays on one side: the halves are a
random split of the units, stratified by recording file (each file's units split in half, an odd
one out to a random side) so that both halves see every recording's speeds and conditions. The
unit is ``run_info["unit"]`` (``"<file>:<follower_position>"``): declare ``group_by="unit"``.
Units of one platoon still share a leader chain (the follower of position 3 is the leader of 4);
the split ignores that, the truth "same population" does not depend on it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from functools import lru_cache

import numpy as np

from response_designs import A_MAX_PHYS, A_MIN, HUMAN, SIGNALS, Driver, idm, tracks
from simcred.traces import RUN_INFO, TraceSet, take

DT = 0.1  # s: simulation and recording step (the OpenACC step)
WINDOW = 25.0  # s: leader window of a closed-loop run (251 samples)
#: AR(1) coefficient per DT with HUMAN's correlation time (phi 0.9 per 0.5 s).
PHI = float(HUMAN.phi ** (DT / 0.5))
TAU = float(-0.5 / np.log(HUMAN.phi))  # s, the noise's correlation time (4.75 s)
T_NOMINAL = 1.5  # s: headway of the shared start state
V_MAX = 28.0  # m/s: shifted leader windows stay in [0, V_MAX]
CLIP = (-1.5, 0.5)  # m/s²: ~ the reference's 0.04 % / 97.5 % quantiles of applied acceleration
CLIP_SYMMETRIC = (-0.5, 0.5)  # m/s²: the brief's clip; crashes 1.2-1.5 % of runs
DELAYS = {"delay_0.15": 0.15, "delay_0.3": 0.3, "delay_0.5": 0.5, "delay_1.0": 1.0}
DEFECTS = ("none", *DELAYS, "clip")
#: Defects outside the study, for diagnostics (``clip_0.5``: runs crash).
DIAGNOSTIC = ("clip_0.5",)
UNITS = {"gap": "m", "dv": "m/s", "v": "m/s", "a": "m/s²", "v_leader": "m/s"}


def samples_of(seconds: float, dt: float = DT) -> int:
    """Samples of a window of ``seconds`` at step ``dt`` (both ends included)."""
    return int(round(seconds / dt)) + 1


def human(rng: np.random.Generator, runs: int) -> Driver:
    """``response_designs.HUMAN`` at step DT: per-run headway T = 1.5 exp(0.15 z) s (the same
    trait), noise sd 0.2 m/s² with the same correlation time (``phi = PHI``)."""
    return replace(HUMAN, T=1.5 * np.exp(0.15 * rng.normal(size=runs)), phi=PHI)


# -- leader windows at 0.1 s -------------------------------------------------------------------


@lru_cache(maxsize=8)
def _pool(samples: int) -> tuple[np.ndarray, np.ndarray]:
    """(track, first sample) of every window of ``samples`` samples at 0.1 s."""
    track, start = [], []
    for k, vl in enumerate(tracks().v_leader):
        n = len(vl) - samples + 1
        if n > 0:
            track.append(np.full(n, k))
            start.append(np.arange(n))
    return np.concatenate(track), np.concatenate(start)


def draw_windows(rng: np.random.Generator, runs: int, seconds: float = WINDOW, *,
                 shift: bool = True) -> dict[str, np.ndarray]:
    """``runs`` distinct leader windows of ``seconds`` at 0.1 s: ``v_leader`` (runs, samples),
    ``track``, ``start``, ``offset`` (the shift added to the recorded profile, 0 without
    ``shift``)."""
    samples = samples_of(seconds)
    track, start = _pool(samples)
    if len(track) < runs:
        raise ValueError(f"only {len(track)} leader windows of {seconds} s, need {runs}")
    pick = np.sort(rng.choice(len(track), size=runs, replace=False))
    track, start = track[pick], start[pick]
    tr = tracks().v_leader
    vl = np.stack([tr[k][s:s + samples] for k, s in zip(track, start, strict=True)])
    lo, hi = -vl.min(axis=1), V_MAX - vl.max(axis=1)
    u = rng.uniform(size=runs)  # drawn either way: the stream does not depend on `shift`
    offset = np.where(hi > lo, lo + u * (hi - lo), 0.0) if shift else np.zeros(runs)
    return {"v_leader": vl + offset[:, None], "track": track, "start": start, "offset": offset}


# -- the closed loop -----------------------------------------------------------------------------


def simulate(rng: np.random.Generator, v_leader: np.ndarray, gap0: np.ndarray, v0: np.ndarray,
             driver: Driver, *, dt: float = DT, delay: float = 0.0,
             clip: tuple[float, float] | None = None) -> dict[str, np.ndarray]:
    """Follower behind ``v_leader`` (runs, samples) at step ``dt`` from (gap0, v0).

    As :func:`response_designs.simulate` (IDM command, AR(1) noise ``driver.sigma`` /
    ``driver.phi`` per step started stationary, applied acceleration limited to [-9, 4] m/s² and
    to ``v >= 0``, ballistic update with the leader speed held over the step), but ``dt`` is an
    argument, ``delay`` is in seconds (the command uses the state ``delay`` s ago, linearly
    interpolated between steps; the start state before t = 0) and ``clip`` bounds the applied
    acceleration. Returns SIGNALS and ``command`` as (runs, samples) arrays; the noise stream is
    the same whatever ``delay`` and ``clip`` (common random numbers across defects)."""
    runs, steps = v_leader.shape
    d = driver
    gap, v, a, cmd = (np.empty((runs, steps)) for _ in range(4))
    gap[:, 0], v[:, 0] = gap0, np.maximum(v0, 0.0)
    sigma = np.broadcast_to(np.asarray(d.sigma, dtype=float), (runs,))
    noise = sigma * rng.normal(size=runs)
    innov = sigma * np.sqrt(1 - d.phi ** 2)
    lag = delay / dt
    whole = int(np.floor(lag + 1e-9))
    frac = lag - whole if lag - whole > 1e-9 else 0.0
    for t in range(steps):
        i, j = max(t - whole, 0), max(t - whole - 1, 0)
        state = [x[:, i] if frac == 0.0 else (1 - frac) * x[:, i] + frac * x[:, j]
                 for x in (gap, v, v_leader)]
        cmd[:, t] = idm(*state, d)
        acc = cmd[:, t] + noise
        if clip is not None:
            acc = np.clip(acc, *clip)
        acc = np.clip(acc, A_MIN, A_MAX_PHYS)
        acc = np.maximum(acc, -v[:, t] / dt)  # stop, never reverse
        a[:, t] = acc
        if t + 1 < steps:
            v[:, t + 1] = v[:, t] + acc * dt
            gap[:, t + 1] = gap[:, t] + (v_leader[:, t] - 0.5 * (v[:, t] + v[:, t + 1])) * dt
            noise = d.phi * noise + innov * rng.normal(size=runs)
    return {"gap": gap, "dv": v_leader - v, "v": v, "a": a, "v_leader": v_leader.copy(),
            "command": cmd}


def to_traceset(sim: Mapping[str, np.ndarray], ids: Sequence[str], info: Sequence[dict],
                source: str, dt: float = DT) -> TraceSet:
    """(runs, samples) arrays of SIGNALS → TraceSet with units and run_info (clock from 0)."""
    runs, steps = sim["gap"].shape
    time = np.tile(np.arange(steps) * dt, runs)
    values = np.stack([sim[s] for s in SIGNALS], axis=2).reshape(-1, len(SIGNALS))
    return TraceSet(SIGNALS, time, values, np.arange(runs + 1) * steps, tuple(ids),
                    {RUN_INFO: dict(zip(ids, info, strict=True)), "units": dict(UNITS)}, source)


def start_state(v_leader: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(gap0, v0): the IDM equilibrium of the nominal headway at the leader's first speed."""
    v0 = v_leader[:, 0].copy()
    d = replace(HUMAN, T=T_NOMINAL)
    return (d.s0 + v0 * d.T) / np.sqrt(1 - (v0 / d.v0) ** 4), v0


def defect_options(defect: str) -> dict:
    """``simulate`` keywords of a defect of :data:`DEFECTS` (or :data:`DIAGNOSTIC`)."""
    if defect not in DEFECTS + DIAGNOSTIC:
        raise ValueError(f"unknown defect {defect!r}; known: {DEFECTS + DIAGNOSTIC}")
    if defect in ("clip", "clip_0.5"):
        return {"clip": CLIP if defect == "clip" else CLIP_SYMMETRIC}
    return {"delay": DELAYS.get(defect, 0.0)}


def closed_loop_pair(rng: np.random.Generator, episodes: int, *, defect: str = "none",
                     seconds: float = WINDOW, shift: bool = True
                     ) -> tuple[TraceSet, TraceSet]:
    """(reference, candidate): the human-like IDM behind ``episodes`` recorded leader windows of
    ``seconds``, and the candidate with ``defect`` replaying the same windows from the same start
    states (same run ids, independent trait and noise). Declare ``pair_by="run_id"``,
    ``inputs=["v_leader"]``. The draws (windows, reference, candidate) come in the same order
    whatever ``defect``: one seed gives the same reference and candidate noise for every defect."""
    options = defect_options(defect)
    leaders = draw_windows(rng, episodes, seconds, shift=shift)
    vl = leaders["v_leader"]
    gap0, v0 = start_state(vl)
    ref_driver, cand_driver = human(rng, episodes), human(rng, episodes)
    ref = simulate(rng, vl, gap0, v0, ref_driver)
    cand = simulate(rng, vl, gap0, v0, cand_driver, **options)
    ids = [f"p{i:04d}" for i in range(episodes)]
    tr = tracks()
    sets = []
    for sim, driver, name, label in ((ref, ref_driver, "none", "reference"),
                                     (cand, cand_driver, defect, "candidate")):
        info = []
        for i in range(episodes):
            k = int(leaders["track"][i])
            info.append({"file": tr.info[k]["file"], "leader_vehicle": tr.info[k]["leader_vehicle"],
                         "follower_vehicle": tr.info[k]["follower_vehicle"],
                         "track": tr.info[k]["episode"], "start_sample": int(leaders["start"][i]),
                         "offset": float(leaders["offset"][i]), "T": float(driver.T[i]),
                         "defect": name})
        sets.append(to_traceset(sim, ids, info, f"closed_loop:{label}:{defect}"))
    return sets[0], sets[1]


def crashed(traces: TraceSet) -> np.ndarray:
    """Per run: did the gap fall below 0?"""
    gap = traces.column("gap")
    return np.minimum.reduceat(gap, traces.offsets[:-1]) < 0


# -- real human halves ---------------------------------------------------------------------------


@lru_cache(maxsize=1)
def human_episodes() -> TraceSet:
    """The OpenACC human-follower episodes, run_info with ``unit`` = ``<file>:<follower pos>``."""
    from simcred.io.openacc import read_openacc

    eps = read_openacc(follower="human")
    info = {r: dict(i) | {"unit": f"{i['file']}:{i['follower_position']}"}
            for r, i in eps.metadata[RUN_INFO].items()}
    return TraceSet(eps.signals, eps.time, eps.values, eps.offsets, eps.run_ids,
                    dict(eps.metadata) | {RUN_INFO: info}, eps.source)


def split_units(rng: np.random.Generator) -> tuple[list[str], list[str]]:
    """Random halves of the units, stratified by file (an odd unit out to a random side)."""
    ri = human_episodes().metadata[RUN_INFO]
    by_file: dict[str, list[str]] = {}
    for info in ri.values():
        units = by_file.setdefault(info["file"], [])
        if info["unit"] not in units:
            units.append(info["unit"])
    halves: tuple[list[str], list[str]] = ([], [])
    for file in sorted(by_file):
        units = [by_file[file][i] for i in rng.permutation(len(by_file[file]))]
        n = len(units) // 2 + (len(units) % 2) * int(rng.integers(2))
        halves[0].extend(units[:n])
        halves[1].extend(units[n:])
    return halves


def human_halves(rng: np.random.Generator, episodes: int | None = None
                 ) -> tuple[TraceSet, TraceSet]:
    """Two random halves of the real human episodes, split by unit (module docs; declare
    ``group_by="unit"``), ``episodes`` per half drawn at random from the half's episodes (capped
    at what the half holds; None: all), in recording order."""
    eps = human_episodes()
    ri = eps.metadata[RUN_INFO]
    unit = np.array([ri[r]["unit"] for r in eps.run_ids])
    sets = []
    for side, units in zip("AB", split_units(rng), strict=True):
        pool = np.flatnonzero(np.isin(unit, units))
        n = len(pool) if episodes is None else min(episodes, len(pool))
        pick = np.sort(rng.choice(pool, size=n, replace=False))
        sets.append(take(eps, pick, source=f"openacc humans: half {side}"))
    return sets[0], sets[1]


#: The ACC car of the "against itself" design: the (vehicle, headway setting) with the most
#: OpenACC ACC episodes (422 in 20 recording files), chosen by count before any verdict was seen.
ACC_CAR = ("MERCEDES_GLE450", "short")


@lru_cache(maxsize=1)
def acc_episodes() -> TraceSet:
    """The OpenACC episodes of :data:`ACC_CAR` on ACC."""
    from simcred.io.openacc import read_openacc

    eps = read_openacc(follower="acc")
    ri = eps.metadata[RUN_INFO]
    keep = [i for i, r in enumerate(eps.run_ids)
            if (ri[r]["follower_vehicle"], ri[r]["setting"]) == ACC_CAR]
    return take(eps, keep, source=f"openacc ACC {ACC_CAR[0]} ({ACC_CAR[1]} setting)")


def acc_halves(rng: np.random.Generator, episodes: int | None = None
               ) -> tuple[TraceSet, TraceSet]:
    """One real ACC car against itself: its recording files split at random into two halves
    (declare ``group_by="file"``: episodes of one recording share its day, leader and traffic),
    ``episodes`` per half drawn at random (capped at what the half holds; None: all), in
    recording order. Truth: valid — one vehicle, one controller, one headway setting."""
    eps = acc_episodes()
    ri = eps.metadata[RUN_INFO]
    file = np.array([ri[r]["file"] for r in eps.run_ids])
    names = sorted(set(file))
    first = set(rng.permutation(names)[: len(names) // 2].tolist())
    sets = []
    for side, mine in zip("AB", (True, False), strict=True):
        pool = np.flatnonzero(np.array([(f in first) == mine for f in file]))
        n = len(pool) if episodes is None else min(episodes, len(pool))
        pick = np.sort(rng.choice(pool, size=n, replace=False))
        sets.append(take(eps, pick, source=f"openacc ACC car: half {side}"))
    return sets[0], sets[1]


__all__ = ["ACC_CAR", "CLIP", "CLIP_SYMMETRIC", "DEFECTS", "DELAYS", "DIAGNOSTIC", "DT", "PHI",
           "WINDOW", "acc_episodes", "acc_halves", "closed_loop_pair", "crashed", "draw_windows",
           "human", "human_halves", "simulate", "split_units"]
