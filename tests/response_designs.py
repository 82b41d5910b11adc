"""Seeded known-truth designs for the response test (and any comparison of two sets of runs).

Every design is a function ``name(rng, **size) -> Design``; two calls with different rng states
give independent data. H0 designs (same law of response given the state in A and B):
:func:`lengths`, :func:`lengths_markov`, :func:`paired_scenarios`, :func:`leaders_split`,
:func:`grouped`, :func:`segments`. H1 designs: :func:`defect` (``kind`` in :data:`DEFECTS`,
``"none"`` being the same-law control). :data:`H0` maps names to the H0 designs at default size.

Driving designs: a follower behind a REAL recorded leader
------------------------------------------------------
Leader speed profiles are the ``v_leader`` column of the OpenACC human-follower episodes
(``read_openacc(follower="human")``: 609 episodes of 10 s at 10 Hz, 4 recordings). Consecutive
episodes of one leader–follower pair (same file and platoon position, episode clocks 10.1 s
apart) are chained into *tracks* (49 tracks, up to 30 episodes, 0.1 s steps without a hole), so
that designs can draw leader windows longer than one episode. A window is a start sample of a
track (any 0.1 s sample) and ``samples`` samples THINNED TO 0.5 s (every fifth 0.1 s sample):
a 10 s episode is 21 samples, 20 transitions.

The follower is simulated at the same 0.5 s step, vectorised over runs (:func:`simulate`):
IDM command ``c = a_max [1 - (v/v0)^4 - (s*/s)^2]``, ``s* = s0 + v T + v (v - v_l) / (2
sqrt(a_max b))``; applied acceleration ``a = c + noise (+ defect)``, limited to [-9, 4] m/s² and
so that ``v >= 0``; ballistic update with the leader speed HELD over the step::

    v[t+1]   = v[t] + a[t] dt
    gap[t+1] = gap[t] + (v_l[t] - (v[t] + v[t+1]) / 2) dt

so (gap, v) at t+1 is a function of (gap, v, v_l, noise) at t: with the noise off (deterministic
IDM, :func:`leaders_split`) the response (gap, v) is a deterministic function of the state
(gap, v, v_leader). Signals written per run (OpenACC units and sign conventions): ``gap`` [m],
``dv`` = v_leader - v [m/s] (positive: the gap opens, as in simcred.io.openacc), ``v`` [m/s],
``a`` [m/s²] the APPLIED acceleration over [t, t + dt) (recorded at the last sample too, where
it is not applied), ``v_leader`` [m/s]. Runs start at the IDM EQUILIBRIUM for the leader's first
speed (dv = 0, the run's own headway T), except :func:`lengths`, which perturbs that gap. (The
recorded humans follow closer than this IDM: started at their recorded gap, most runs would open
with a 2-9 m/s² brake; :func:`driving_set` still offers start="recorded".)

The stochastic human-like driver (:data:`HUMAN`) is that IDM (v0 30 m/s, s0 2 m, a_max 1.0 m/s²,
b 1.5 m/s²) with a per-run time headway ``T = 1.5 exp(0.15 z)`` s (z ~ N(0, 1)) and AR(1)
acceleration noise ``e[t+1] = 0.9 e[t] + sigma w`` started stationary, stationary sd 0.2 m/s²:
behind recorded leaders var(a) is 0.063 m²/s⁴ without noise and 0.079 with it (the closed loop
absorbs most of the noise's 0.04; :func:`noise_share`), so the noise is visible, IDM dominates.

Caveat about the truth of the driving H0 designs: they are "same generating process" designs.
The law of the next (binned) values given a BINNED state is the same in A and B only up to two
effects every test on a discretised state must live with: the distribution of the continuous
state inside a bin, and the hidden noise state / per-run trait, can differ between A and B when
the designs visit states differently (that is the point of ``lengths``, ``leaders_split``,
``grouped``). :func:`lengths_markov` is an exact H0 (a first-order chain on discrete values).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np

from simcred.traces import RUN_INFO, TraceSet

DT = 0.5  # s, the simulation and recording step (OpenACC's 0.1 s thinned by 5)
THIN = 5
EPISODE = 21  # samples of a 10 s episode at 0.5 s
SIGNALS = ("gap", "dv", "v", "a", "v_leader")
#: State features of the driving designs (leaders_split: LEADER_FEATURES, v_leader an input).
FEATURES = ("gap", "dv", "v", "a")
LEADER_FEATURES = ("gap", "v", "v_leader")
A_MIN, A_MAX_PHYS = -9.0, 4.0


@dataclass(frozen=True)
class Design:
    """Two sets of runs and how they are to be compared."""

    a: TraceSet
    b: TraceSet
    features: tuple[str, ...]  # signals that span the state (inputs included)
    inputs: tuple[str, ...] = ()  # exogenous signals among the features
    pair_by: str | None = None  # "run_id" when A and B are paired replays
    group_by: str | None = None  # run_info key of the exchangeable unit


@dataclass(frozen=True)
class Driver:
    """IDM parameters, noise and defects of a simulated follower (scalars or per-run arrays)."""

    v0: Any = 30.0  # desired speed [m/s]
    s0: Any = 2.0  # jam distance [m]
    T: Any = 1.5  # time headway [s]
    a_max: Any = 1.0  # maximum acceleration [m/s²]
    b: Any = 1.5  # comfortable deceleration [m/s²]
    sigma: Any = 0.2  # stationary sd of the AR(1) acceleration noise [m/s²] (0: deterministic)
    phi: float = 0.9  # AR(1) coefficient per 0.5 s step
    # defects
    bias: float = 0.0  # added to the applied acceleration [m/s²]
    gain: float = 1.0  # multiplies the IDM command (not the noise)
    delay: int = 0  # steps: the IDM command uses the state `delay` steps ago
    late: Any = 0  # steps (per run): braking commands applied `late` steps late
    clip: tuple[float, float] | None = None  # applied acceleration clipped to [lo, hi]
    gap_gain: float = 1.0  # the recorded gap × gap_gain (a sensor gain; the driver sees the truth)


#: The stochastic human-like driver; per-run headway is drawn by :func:`human`.
HUMAN = Driver()
DETERMINISTIC = Driver(sigma=0.0)


def human(rng: np.random.Generator, runs: int, **changes: Any) -> Driver:
    """HUMAN with a per-run time headway T = 1.5 exp(0.15 z) s (a per-run trait)."""
    return replace(HUMAN, T=1.5 * np.exp(0.15 * rng.normal(size=runs)), **changes)


# -- recorded leaders ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Tracks:
    """OpenACC leader–follower tracks at 0.1 s: chained consecutive episodes of one pair."""

    v_leader: tuple[np.ndarray, ...]
    gap: tuple[np.ndarray, ...]
    v: tuple[np.ndarray, ...]
    info: tuple[dict, ...]  # file, leader/follower vehicle, positions, first episode id


@lru_cache(maxsize=1)
def tracks() -> Tracks:
    """Load the shipped OpenACC human-follower episodes once and chain them into tracks."""
    from simcred.io.openacc import read_openacc

    eps = read_openacc(follower="human")
    ri = eps.metadata[RUN_INFO]
    chains: list[list[int]] = []
    for i, rid in enumerate(eps.run_ids):
        info = ri[rid]
        if chains:
            prev = ri[eps.run_ids[chains[-1][-1]]]
            if (prev["file"], prev["leader_position"]) == (info["file"], info["leader_position"]) \
                    and abs(info["t0"] - prev["t0"] - 10.1) < 1e-6:
                chains[-1].append(i)
                continue
        chains.append([i])
    cols = {s: eps.column(s) for s in ("v_leader", "gap", "v")}
    out: dict[str, list] = {"v_leader": [], "gap": [], "v": [], "info": []}
    for chain in chains:
        rows = np.concatenate([np.arange(eps.offsets[i], eps.offsets[i + 1]) for i in chain])
        for s in cols:
            out[s].append(cols[s][rows])
        first = ri[eps.run_ids[chain[0]]]
        out["info"].append({k: first[k] for k in ("file", "leader_vehicle", "follower_vehicle",
                                                  "leader_position")}
                           | {"episode": eps.run_ids[chain[0]], "episodes": len(chain)})
    return Tracks(*(tuple(out[k]) for k in ("v_leader", "gap", "v", "info")))


@lru_cache(maxsize=16)
def windows(samples: int) -> dict[str, np.ndarray]:
    """Every window of ``samples`` samples at 0.5 s in every track: track index, first 0.1 s
    sample, leader speeds (windows, samples), recorded follower gap/speed at the first sample,
    the window's mean leader speed and file."""
    tr = tracks()
    span = (samples - 1) * THIN + 1
    track, start = [], []
    for k, vl in enumerate(tr.v_leader):
        n = len(vl) - span + 1
        if n > 0:
            track.append(np.full(n, k))
            start.append(np.arange(n))
    track, start = np.concatenate(track), np.concatenate(start)
    idx = start[:, None] + THIN * np.arange(samples)[None, :]
    vl = np.empty((len(track), samples))
    for k in np.unique(track):
        sel = track == k
        vl[sel] = tr.v_leader[k][idx[sel]]
    gap0 = np.array([tr.gap[k][s] for k, s in zip(track, start, strict=True)])
    v0 = np.array([tr.v[k][s] for k, s in zip(track, start, strict=True)])
    files = np.array([tr.info[k]["file"] for k in track])
    out = {"track": track, "start": start, "v_leader": vl, "gap0": gap0, "v0": v0,
           "mean_speed": vl.mean(axis=1), "file": files}
    for v in out.values():
        v.setflags(write=False)
    return out


def draw_leaders(rng: np.random.Generator, runs: int, samples: int = EPISODE,
                 mask: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """``runs`` distinct leader windows (among those where ``mask`` holds)."""
    w = windows(samples)
    pool = np.flatnonzero(mask) if mask is not None else np.arange(len(w["track"]))
    if len(pool) < runs:
        raise ValueError(f"only {len(pool)} leader windows of {samples} samples, need {runs}")
    pick = rng.choice(pool, size=runs, replace=False)
    return {k: v[pick] for k, v in w.items()}


# -- the follower ----------------------------------------------------------------------------------


def idm(gap, v, vl, d: Driver) -> np.ndarray:
    s_star = d.s0 + np.maximum(0.0, v * d.T + v * (v - vl) / (2 * np.sqrt(d.a_max * d.b)))
    return d.a_max * (1 - (v / d.v0) ** 4 - (s_star / np.maximum(gap, 0.1)) ** 2)


def simulate(rng: np.random.Generator, v_leader: np.ndarray, gap0: np.ndarray, v0: np.ndarray,
             driver: Driver) -> dict[str, np.ndarray]:
    """Follower behind ``v_leader`` (runs, samples) at step DT, from (gap0, v0): every signal of
    SIGNALS as a (runs, samples) array, plus ``command`` (the IDM part of the acceleration)."""
    runs, steps = v_leader.shape
    d = driver
    gap, v, a = np.empty((runs, steps)), np.empty((runs, steps)), np.empty((runs, steps))
    cmd = np.empty((runs, steps))
    gap[:, 0], v[:, 0] = gap0, np.maximum(v0, 0.0)
    sigma = np.broadcast_to(np.asarray(d.sigma, dtype=float), (runs,))
    noise = sigma * rng.normal(size=runs)
    innov = sigma * np.sqrt(1 - d.phi ** 2)
    late = np.broadcast_to(np.asarray(d.late, dtype=int), (runs,))
    rows = np.arange(runs)
    for t in range(steps):
        lag = max(t - d.delay, 0)
        cmd[:, t] = d.gain * idm(gap[:, lag], v[:, lag], v_leader[:, lag], d)
        c = cmd[:, t]
        if late.any():  # braking applied `late` steps late: coast until then (0 before t = 0)
            back = t - late
            earlier = np.where(back >= 0, cmd[rows, np.maximum(back, 0)], 0.0)
            c = np.where((late > 0) & (c < 0), np.minimum(earlier, 0.0), c)
        acc = c + noise + d.bias
        if d.clip is not None:
            acc = np.clip(acc, *d.clip)
        acc = np.clip(acc, A_MIN, A_MAX_PHYS)
        acc = np.maximum(acc, -v[:, t] / DT)  # stop, never reverse
        a[:, t] = acc
        if t + 1 < steps:
            v[:, t + 1] = v[:, t] + acc * DT
            gap[:, t + 1] = gap[:, t] + (v_leader[:, t] - 0.5 * (v[:, t] + v[:, t + 1])) * DT
            noise = d.phi * noise + innov * rng.normal(size=runs)
    return {"gap": gap, "dv": v_leader - v, "v": v, "a": a, "v_leader": v_leader.copy(),
            "command": cmd}


def equilibrium_gap(v, d: Driver = HUMAN):
    """IDM equilibrium gap at speed v (dv = 0)."""
    return (d.s0 + v * d.T) / np.sqrt(1 - (v / d.v0) ** 4)


def to_traceset(sim: Mapping[str, np.ndarray], ids: Sequence[str], info: Sequence[dict],
                source: str, t0: np.ndarray | None = None) -> TraceSet:
    """(runs, samples) arrays of SIGNALS → TraceSet, run_info per run."""
    runs, steps = sim["gap"].shape
    t = np.arange(steps) * DT
    time = (t[None, :] + (np.zeros(runs) if t0 is None else np.asarray(t0))[:, None]).reshape(-1)
    values = np.stack([sim[s] for s in SIGNALS], axis=2).reshape(-1, len(SIGNALS))
    return TraceSet(SIGNALS, time, values, np.arange(runs + 1) * steps, tuple(ids),
                    {RUN_INFO: dict(zip(ids, info, strict=True)),
                     "units": {"gap": "m", "dv": "m/s", "v": "m/s", "a": "m/s²",
                               "v_leader": "m/s"}},
                    source)


def _info(leaders: Mapping[str, np.ndarray], i: int, **extra: Any) -> dict:
    tr = tracks()
    k = int(leaders["track"][i])
    return {"file": tr.info[k]["file"], "leader_vehicle": tr.info[k]["leader_vehicle"],
            "track": tr.info[k]["episode"], "start_sample": int(leaders["start"][i]), **extra}


def _scalar(x, i):
    x = np.asarray(x)
    return float(x) if x.ndim == 0 else float(x[i])


def driving_set(rng: np.random.Generator, leaders: Mapping[str, np.ndarray], driver: Driver,
                ids: Sequence[str], source: str, start: str = "equilibrium",
                extra: Sequence[dict] | None = None) -> TraceSet:
    """Simulate ``driver`` behind ``leaders`` and return the TraceSet. ``start``: "equilibrium"
    (IDM equilibrium gap of each run's own T at the leader's first speed, dv = 0), "perturbed"
    (that gap × exp(N(0, 0.3))) or "recorded" (the recorded follower's gap and speed; the
    recorded humans follow closer than this IDM, so most runs then open with a hard brake)."""
    vl = leaders["v_leader"]
    if start == "recorded":
        gap0, v0 = leaders["gap0"], leaders["v0"]
    else:  # IDM equilibrium (the run's own T) at the leader's first speed, dv = 0
        v0 = vl[:, 0].copy()
        gap0 = equilibrium_gap(v0, driver)
        if start == "perturbed":  # gap × exp(N(0, 0.3))
            gap0 = gap0 * np.exp(0.3 * rng.normal(size=len(v0)))
    sim = simulate(rng, vl, gap0, v0, driver)
    sim["gap"] = sim["gap"] * driver.gap_gain
    info = [_info(leaders, i, T=_scalar(driver.T, i), late=_scalar(driver.late, i),
                  **(extra[i] if extra else {})) for i in range(len(ids))]
    return to_traceset(sim, ids, info, source)


def _ids(prefix: str, n: int) -> list[str]:
    return [f"{prefix}{i:03d}" for i in range(n)]


# -- H0 designs ----------------------------------------------------------------------------------


def lengths(rng: np.random.Generator, runs: int = 40, short: int = 10, long: int = 100) -> Design:
    """Same human-like driver; A's runs have ``short`` samples (0.5 s), B's ``long``. Runs start
    at the IDM equilibrium gap for the leader's first speed times exp(N(0, 0.3)): a start
    transient that short runs spend all their time in, long runs a small part."""
    sets = []
    for side, n in (("A", short), ("B", long)):
        leaders = draw_leaders(rng, runs, n)
        sets.append(driving_set(rng, leaders, human(rng, runs), _ids(side.lower(), runs),
                                f"lengths:{side}", start="perturbed"))
    return Design(sets[0], sets[1], FEATURES)


def lengths_markov(rng: np.random.Generator, runs: int = 40, short: int = 10,
                   long: int = 100) -> Design:
    """Exact H0: one first-order Markov chain on x in {0..3} (y a fair coin), started uniformly
    (not stationary): A's runs have ``short`` steps, B's ``long`` (tests/compare_designs.py)."""
    from compare_designs import markov

    return Design(markov(rng, [short] * runs), markov(rng, [long] * runs), ("x", "y"))


def _mixture_leaders(rng, pairs, samples=EPISODE):
    """Half the windows from slow leaders (mean speed in the lowest quartile of windows), half
    from fast ones (highest quartile), in random order."""
    w = windows(samples)
    lo, hi = np.quantile(w["mean_speed"], [0.25, 0.75])
    slow = draw_leaders(rng, pairs // 2, samples, w["mean_speed"] <= lo)
    fast = draw_leaders(rng, pairs - pairs // 2, samples, w["mean_speed"] >= hi)
    order = rng.permutation(pairs)
    return {k: np.concatenate([slow[k], fast[k]])[order] for k in slow}


def paired_scenarios(rng: np.random.Generator, pairs: int = 40) -> Design:
    """Paired replays: pair i = one scenario (a recorded leader window; start at the IDM
    equilibrium for its first speed), half of the pairs behind slow leaders (lowest quartile of
    mean speed, ~12 m/s), half behind fast ones (highest quartile, ~16 m/s). A ("reality") and
    B ("replay") are the same human-like driver model with independent noise and independent
    per-run headway draws (the trait belongs to the driver, not the scenario). Same run ids;
    pair_by="run_id"."""
    leaders = _mixture_leaders(rng, pairs)
    ids = _ids("p", pairs)
    extra = [{"band": "slow" if m < np.median(leaders["mean_speed"]) else "fast"}
             for m in leaders["mean_speed"]]
    a = driving_set(rng, leaders, human(rng, pairs), ids, "paired:A", extra=extra)
    b = driving_set(rng, leaders, human(rng, pairs), ids, "paired:B", extra=extra)
    return Design(a, b, FEATURES, pair_by="run_id")


#: The two halves of the OpenACC human-follower recordings (median leader speed 13.2 / 15.7 m/s).
HALVES = (("no_ACC/handling_part22", "no_ACC/handling_part35"),
          ("no_ACC/handling_part26", "no_ACC/handling_part40"))


def leaders_split(rng: np.random.Generator, runs: int = 40) -> Design:
    """One DETERMINISTIC IDM (T = 1.5 s, no noise, no trait) behind leaders of two different
    halves of the recordings (HALVES: slower vs faster platoons); which half is A is drawn per
    call. Features (gap, v, v_leader) with v_leader an input: the response (gap, v) at t+1 is a
    deterministic function of (gap, v, v_leader) at t, the same in A and B. Not paired."""
    w = windows(EPISODE)
    first = int(rng.integers(2))
    sets = []
    for side, half in (("A", HALVES[first]), ("B", HALVES[1 - first])):
        leaders = draw_leaders(rng, runs, EPISODE, np.isin(w["file"], half))
        sets.append(driving_set(rng, leaders, DETERMINISTIC, _ids(side.lower(), runs),
                                f"leaders_split:{side}"))
    return Design(sets[0], sets[1], LEADER_FEATURES, inputs=("v_leader",))


def group_traits(rng: np.random.Generator, groups: int) -> dict[str, np.ndarray]:
    """Driver population: T = 1.5 exp(0.25 z1) s, a_max = exp(0.3 z2) m/s², noise sd
    0.2 exp(0.4 z3) m/s²."""
    z = rng.normal(size=(3, groups))
    return {"T": 1.5 * np.exp(0.25 * z[0]), "a_max": np.exp(0.3 * z[1]),
            "sigma": 0.2 * np.exp(0.4 * z[2])}


def grouped(rng: np.random.Generator, groups: int = 8, runs_per_group: int = 5) -> Design:
    """``groups`` drivers per side, each with its own (T, a_max, noise sd) from one population
    (:func:`group_traits`), ``runs_per_group`` runs each behind random recorded leaders. A and B
    are independent draws of drivers. run_info["driver"] = "A.d3" / "B.d3"; group_by="driver"."""
    n = groups * runs_per_group
    sets = []
    for side in ("A", "B"):
        tr = group_traits(rng, groups)
        g = np.repeat(np.arange(groups), runs_per_group)
        driver = replace(HUMAN, **{k: v[g] for k, v in tr.items()})
        leaders = draw_leaders(rng, n)
        ids = [f"{side.lower()}.d{gi}.r{j}" for gi in range(groups) for j in range(runs_per_group)]
        extra = [{"driver": f"{side}.d{gi}", "a_max": float(tr["a_max"][gi]),
                  "sigma": float(tr["sigma"][gi])} for gi in g]
        sets.append(driving_set(rng, leaders, driver, ids, f"grouped:{side}", extra=extra))
    return Design(sets[0], sets[1], FEATURES, group_by="driver")


def segments(rng: np.random.Generator, runs: int = 20, segments: int = 4,
             samples: int = 20) -> Design:
    """Long runs (``segments`` × ``samples`` samples at 0.5 s behind one recorded leader track,
    so the run stays in that platoon's speed band) of a driver with a per-run trait (T =
    1.5 exp(0.25 z) s, noise sd 0.2 exp(0.3 z') m/s²), cut into consecutive segments stored as
    runs "r007.s2" with run_info["run"] = "r007"; group_by="run". Segments keep the parent
    run's clock."""
    total = segments * samples
    sets = []
    for side in ("A", "B"):
        leaders = draw_leaders(rng, runs, total)
        z = rng.normal(size=(2, runs))
        driver = replace(HUMAN, T=1.5 * np.exp(0.25 * z[0]), sigma=0.2 * np.exp(0.3 * z[1]))
        v0 = leaders["v_leader"][:, 0]
        sim = simulate(rng, leaders["v_leader"], equilibrium_gap(v0, driver), v0, driver)
        cut = {k: v.reshape(runs * segments, samples) for k, v in sim.items()}
        parents = [f"{side.lower()}{i:03d}" for i in range(runs)]
        ids = [f"{p}.s{s}" for p in parents for s in range(segments)]
        info = [_info(leaders, i, run=parents[i], segment=s, T=float(driver.T[i]))
                for i in range(runs) for s in range(segments)]
        t0 = np.tile(np.arange(segments) * samples * DT, runs)
        sets.append(to_traceset(cut, ids, info, f"segments:{side}", t0))
    return Design(sets[0], sets[1], FEATURES, group_by="run")


# -- H1 designs ----------------------------------------------------------------------------------

DELAY_STEPS = 1  # 0.5 s
LATE_STEPS = 2  # 1.0 s
#: Defect kinds (magnitudes fixed in advance, not tuned): a Driver change given A's data.
DEFECTS = ("none", "bias", "delay", "variance", "late_brake_10", "late_brake_50", "clip", "gain",
           "gap_gain", "clip_fixed")
POPULATION_RUNS = 1500  # A's runs whose acceleration quantiles are clip_fixed's bounds


@lru_cache(maxsize=1)
def population_clip() -> tuple[float, float]:
    """The 7.5 % / 92.5 % quantiles of A's applied accelerations over POPULATION_RUNS runs (a
    fixed seed): ``clip``'s bounds without their dependence on the sample's own A."""
    a = defect(np.random.default_rng(7_500_925), "none", runs=POPULATION_RUNS).a
    lo, hi = np.quantile(a.column("a"), [0.075, 0.925])
    return float(lo), float(hi)


def _defective(rng: np.random.Generator, kind: str, base: Driver, runs: int,
               a_accel: np.ndarray) -> Driver:
    if kind == "none":
        return base
    if kind == "bias":
        return replace(base, bias=0.1)
    if kind == "delay":
        return replace(base, delay=DELAY_STEPS)
    if kind == "variance":
        return replace(base, sigma=np.asarray(base.sigma) * 1.5)
    if kind in ("late_brake_10", "late_brake_50"):
        share = 0.1 if kind == "late_brake_10" else 0.5
        late = np.zeros(runs, dtype=int)
        late[rng.choice(runs, size=int(round(share * runs)), replace=False)] = LATE_STEPS
        return replace(base, late=late)
    if kind == "clip":
        lo, hi = np.quantile(a_accel, [0.075, 0.925])
        return replace(base, clip=(float(lo), float(hi)))
    if kind == "clip_fixed":
        return replace(base, clip=population_clip())
    if kind == "gain":
        return replace(base, gain=0.9)
    if kind == "gap_gain":
        return replace(base, gap_gain=0.9)
    raise ValueError(f"unknown defect {kind!r}; known: {DEFECTS}")


def defect(rng: np.random.Generator, kind: str, runs: int = 40, paired: bool = True) -> Design:
    """A = the human-like driver behind recorded leaders (equilibrium starts); B = the same
    driver with one defect:

    * ``bias``: applied acceleration + 0.1 m/s²;
    * ``delay``: the IDM command is computed from the state 0.5 s (one step) ago;
    * ``variance``: noise sd × 1.5;
    * ``late_brake_10`` / ``late_brake_50``: in 10 % / 50 % of B's runs, braking commands are
      applied 1.0 s late (where the command is < 0 the driver applies the command of 1 s
      earlier if that was braking, else coasts at 0; non-braking commands are on time);
    * ``clip``: B's applied acceleration clipped to the 7.5 % / 92.5 % quantiles of A's
      accelerations (this call's A); in the closed loop ~18 % of B's samples sit at a bound and
      ~1.3 % of B's runs end in a collision (gap < 0: the clipped brake is too weak);
    * ``clip_fixed``: the same clipping at :func:`population_clip`'s bounds, fixed in advance:
      B's law does not depend on this call's A, so the pairs are independent draws (what an
      interval's coverage over replications assumes; ``clip`` ties every B run to all of A);
    * ``gain``: the IDM command (not the noise) × 0.9;
    * ``gap_gain``: B's recorded gap × 0.9 (a gain on one feature, as a miscalibrated sensor
      would give; the driver acts on the true gap);
    * ``none``: no defect (control).

    paired=True: B replays A's scenarios (same leader windows, start states and run ids;
    independent noise and headway draws), pair_by="run_id"; else B has its own leader draws and
    run ids. ``late_brake`` before t = 0 counts as no braking (coast)."""
    if kind not in DEFECTS:
        raise ValueError(f"unknown defect {kind!r}; known: {DEFECTS}")
    leaders = draw_leaders(rng, runs)
    ids_a = _ids("p" if paired else "a", runs)
    a = driving_set(rng, leaders, human(rng, runs), ids_a, f"defect:{kind}:A")
    leaders_b = leaders if paired else draw_leaders(rng, runs)
    ids_b = ids_a if paired else _ids("b", runs)
    driver = _defective(rng, kind, human(rng, runs), runs, a.column("a"))
    b = driving_set(rng, leaders_b, driver, ids_b, f"defect:{kind}:B")
    return Design(a, b, FEATURES, pair_by="run_id" if paired else None)


#: H0 designs at their default sizes.
H0: dict[str, Callable[[np.random.Generator], Design]] = {
    "lengths": lengths,
    "lengths_markov": lengths_markov,
    "paired_scenarios": paired_scenarios,
    "leaders_split": leaders_split,
    "grouped": grouped,
    "segments": segments,
}


def noise_share(rng: np.random.Generator, runs: int = 400) -> dict[str, float]:
    """Variance of the applied acceleration of the human-like driver and the part that is the
    noise (a - command), behind recorded leaders: a sanity figure for the docs."""
    leaders = draw_leaders(rng, runs)
    d = human(rng, runs)
    v0 = leaders["v_leader"][:, 0]
    sim = simulate(rng, leaders["v_leader"], equilibrium_gap(v0, d), v0, d)
    return {"var_a": float(sim["a"].var()), "var_noise": float((sim["a"] - sim["command"]).var()),
            "var_command": float(sim["command"].var()), "min_gap": float(sim["gap"].min())}


__all__ = ["DEFECTS", "Design", "Driver", "FEATURES", "H0", "HUMAN", "LEADER_FEATURES",
           "defect", "grouped", "leaders_split", "lengths", "lengths_markov", "paired_scenarios",
           "segments", "simulate"]
