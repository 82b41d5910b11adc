"""The Time-To-React search of [1]: the latest start of an evasive EGO maneuver that still avoids
a predicted collision, for many (scene, object, prediction) rows at once.

The evasive maneuvers (full braking, kickdown, steering one lane left or right) are checked here
(:func:`hits`); :func:`search_ttr` scans the start times and refines the TTR by bisection. The
rows come from :func:`simcred.risk.ttr.risk`, which also maps the TTRs to the risk.

References
----------
[1] S. Wagner, K. Groh, T. Kuehbeck, M. Doerfel, A. Knoll, "Using Time-To-React Based on
    Naturalistic Traffic Object Behavior for Scenario-Based Risk Assessment of Automated Driving",
    IEEE Intelligent Vehicles Symposium (IV), 2018, pp. 1521-1528.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from simcred.risk.prediction import (
    EvasionSet,
    PredictedPath,
    heading_vector,
    rectangles_overlap,
    travel_distance,
    unit_vector,
)
from simcred.risk.scene import Lanes

# the bisection treats rows whose last avoidable grid start lies within this many samples together
_BISECTION_GROUP = 10


@dataclass(frozen=True, slots=True)
class CollidingRows:
    """(scene, object, prediction) triples whose plan collides, with what the search needs."""

    to: tuple[np.ndarray, ...]     # TO x, y, cos, sin, each (rows, T)
    to_half: tuple[np.ndarray, np.ndarray]  # TO half length and width, (rows, 1)
    ego_x: np.ndarray              # planned EGO travel ξ(t), (rows, T)
    ego_y: np.ndarray
    ego_slope: np.ndarray
    ego_speed: np.ndarray
    ego_v0: np.ndarray             # (rows, 1): longitudinal speed and acceleration at the scene
    ego_a0: np.ndarray
    ego_path: PredictedPath                # lateral path, parameters (rows, 1)
    ego_half: tuple[np.ndarray, np.ndarray]


def avoids(r: CollidingRows, idx: np.ndarray, start: np.ndarray, j0: int, times: np.ndarray,
            evasion: EvasionSet, lanes: Lanes) -> np.ndarray:
    """(rows, maneuvers): maneuver started at ``start`` (rows,) avoids the TO at times[j0:].

    Maneuvers are tried in order, each only on the rows no earlier maneuver avoids: a row's
    first avoiding maneuver (and whether there is one) is exact, later columns of a row that
    is already avoided stay False. The EGO follows its plan before ``start``; collisions are
    checked on the samples ``times[j0:]`` only, so ``times[j0 - 1]`` must not be a planned
    collision.
    """
    ok = np.zeros((idx.size, len(evasion.maneuvers)), dtype=bool)
    pending = np.arange(idx.size)
    for m, name in enumerate(evasion.maneuvers):
        ok[pending, m] = ~hits(r, idx[pending], start[pending], j0, times, name, evasion,
                                lanes)
        pending = pending[~ok[pending, m]]
        if not pending.size:
            break
    return ok


def hits(r: CollidingRows, idx: np.ndarray, start: np.ndarray, j0: int, times: np.ndarray,
         name: str, evasion: EvasionSet, lanes: Lanes) -> np.ndarray:
    """(rows,): maneuver ``name`` started at ``start`` still hits the TO at times[j0:]."""
    if name in ("brake", "kickdown"):
        return _hits_longitudinal(r, idx, start, j0, times, name, evasion)
    t = times[j0:]
    s = start[:, None]
    to = tuple(a[idx, j0:] for a in r.to) + tuple(a[idx] for a in r.to_half)
    v0, a0 = r.ego_v0[idx], r.ego_a0[idx]
    half = (r.ego_half[0][idx], r.ego_half[1][idx])
    v_s = travel_distance(v0, a0, s)[1]
    # smoothstep lateral offset of one lane width over `duration`, travel as planned
    sign = 1.0 if name == "left" else -1.0
    duration = evasion.steer_duration(lanes.width)
    u = np.clip((t - s) / duration, 0.0, 1.0)
    y = r.ego_y[idx, j0:] + sign * lanes.width * u * u * u * (10.0 + u * (-15.0 + 6.0 * u))
    dydt = sign * lanes.width / duration * 30.0 * u * u * (1.0 - u) ** 2
    speed = r.ego_speed[idx, j0:]
    cos, sin = unit_vector(speed, r.ego_slope[idx, j0:] * speed + dydt)
    v_end = travel_distance(v0, a0, s + duration)[1]
    unusable = np.minimum(v_s, v_end)[:, 0] < evasion.min_steer_speed
    return unusable | rectangles_overlap((r.ego_x[idx, j0:], y, cos, sin, *half), to).any(axis=1)


def _hits_longitudinal(r: CollidingRows, idx: np.ndarray, start: np.ndarray, j0: int,
                       times: np.ndarray, name: str, evasion: EvasionSet) -> np.ndarray:
    """:func:`hits` of full braking or kickdown (instantaneous from ``start`` on, lateral path
    unchanged).

    The EGO's travel ξ comes first: a row whose every sample is further apart along x than
    the circumscribed circles reach (dx² > reach², the test :func:`rectangles_overlap` starts
    with, evaluated on the same numbers) cannot hit, and its lateral position, heading and
    rectangle test are skipped. Exact: dx² + dy² >= dx² in floating point too."""
    xi = _travel(r, idx, start, j0, times, name, evasion)
    half = (r.ego_half[0][idx], r.ego_half[1][idx])
    to_half = (r.to_half[0][idx], r.to_half[1][idx])
    dx = r.to[0][idx, j0:] - xi
    reach = np.hypot(*half) + np.hypot(*to_half)
    close = np.flatnonzero(~(dx * dx > reach * reach).all(axis=1))
    out = np.zeros(idx.size, dtype=bool)
    if close.size:
        rows = idx[close]
        path = PredictedPath(r.ego_path.y0[rows], tuple(b[rows] for b in r.ego_path.b),
                             r.ego_path.length[rows])
        y, slope = path.at(xi[close])
        to = tuple(a[rows, j0:] for a in r.to) + (to_half[0][close], to_half[1][close])
        out[close] = rectangles_overlap((xi[close], y, *heading_vector(slope), half[0][close],
                                         half[1][close]), to).any(axis=1)
    return out


def _travel(r: CollidingRows, idx: np.ndarray, start: np.ndarray, j0: int, times: np.ndarray,
            name: str, evasion: EvasionSet) -> np.ndarray:
    """The EGO's travel ξ (rows, samples) under full braking or kickdown from ``start``."""
    t = times[j0:]
    s = start[:, None]
    xi_s, v_s = travel_distance(r.ego_v0[idx], r.ego_a0[idx], s)
    since = np.maximum(t - s, 0.0)
    if name == "brake":
        travel = travel_distance(v_s, evasion.brake_acceleration, since)[0]
    else:
        travel = evasion.kickdown_travel(v_s, since)[0]
    return np.where(t > s, xi_s + travel, r.ego_x[idx, j0:])


def search_ttr(r: CollidingRows, first: np.ndarray, times: np.ndarray, evasion: EvasionSet,
               lanes: Lanes, *, work_samples: int) -> tuple[np.ndarray, np.ndarray]:
    """TTR and maneuver code of every row; ``first`` (rows,) is the index of the first planned
    collision sample, >= 1.

    Scan: start indices k = 0, q, 2q, ... (q = ``evasion.scan_step``) while every earlier
    start was avoidable by some maneuver (monotone-safe: the TTR is the end of the avoidable
    prefix, not the last avoidable start); the first start that is not (a start at the planned
    collision, index ``first``, never is) ends the prefix, and the TTR lies between the last
    avoidable start and min(that start, first). Bisection on that interval then refines it
    (prefix assumed within it) to ``dt / 2**bisection_steps`` and returns its lower end, the
    latest start known to be avoidable. Starts are evaluated in blocks (several per numpy call)
    when few rows are active, of at most about ``work_samples`` samples; results do not depend
    on that.
    """
    lo_idx, hi_idx, code = scan_ttr(r, first, times, evasion, lanes, work_samples=work_samples)
    return bisect_ttr(r, lo_idx, hi_idx, code, times, evasion, lanes)


def scan_ttr(r: CollidingRows, first: np.ndarray, times: np.ndarray, evasion: EvasionSet,
             lanes: Lanes, *, work_samples: int,
             prune: Callable[[np.ndarray], np.ndarray] | None = None,
             rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scan of :func:`search_ttr`: per row the last avoidable scanned start index (-1:
    none), the end of the interval holding the TTR, and the maneuver code at that start. The
    TTR that :func:`bisect_ttr` refines is at least ``times[lo_idx]`` (0 where ``lo_idx`` is
    -1).

    ``prune``: called after every block with the current ``lo_idx`` (lower ends of every
    row's TTR), returns the rows (bool) still worth scanning; the others stop where they are
    (their ``lo_idx`` stays a lower end, not the scan's).

    ``rows``: scan only these rows (indices); the others keep ``lo_idx`` -1, ``hi_idx``
    ``first`` and code -1."""
    q = evasion.scan_step
    lo_idx = np.full(first.size, -1)              # last avoidable start; -1: none (TTR 0)
    hi_idx = first.copy()
    code = np.full(first.size, -1)
    active = np.arange(first.size) if rows is None else np.asarray(rows)
    k = 0
    while active.size:
        # a block of start indices k, k + q, ... at once: fewer, larger numpy calls
        work = active.size * (times.size - k) * len(evasion.maneuvers)
        block = int(np.clip(work_samples // max(work, 1), 1, (times.size - 2 - k) // q + 1))
        index = k + q * np.arange(block)
        pair_row, pair_start = np.repeat(active, block), np.tile(index, active.size)
        # a start at or after the planned collision never avoids it (the plan's own sample
        # collides): not evaluated
        before = np.flatnonzero(pair_start < first[pair_row])
        ok = np.zeros((pair_row.size, len(evasion.maneuvers)), dtype=bool)
        ok[before] = avoids(r, pair_row[before], times[pair_start[before]], k + 1, times,
                            evasion, lanes)
        can = ok.any(axis=1).reshape(active.size, block)
        codes = np.argmax(ok, axis=1).reshape(active.size, block)
        ends = np.where(can.all(axis=1), block, np.argmin(can, axis=1))  # first failing start
        has = ends > 0
        last = np.maximum(ends - 1, 0)
        code[active[has]] = codes[has, last[has]]
        lo_idx[active[has]] = index[last[has]]
        stopped = ends < block
        hi_idx[active[stopped]] = np.minimum(index[ends[stopped]], first[active[stopped]])
        active = active[~stopped]
        k += q * block
        active = active[first[active] > k]       # the next start is at or after the collision
        if prune is not None and active.size:
            active = active[prune(lo_idx)[active]]
    return lo_idx, hi_idx, code


def bisect_ttr(r: CollidingRows, lo_idx: np.ndarray, hi_idx: np.ndarray, code: np.ndarray,
               times: np.ndarray, evasion: EvasionSet, lanes: Lanes,
               only: np.ndarray | None = None, group_size: int = _BISECTION_GROUP
               ) -> tuple[np.ndarray, np.ndarray]:
    """The bisection of :func:`search_ttr` after :func:`scan_ttr`: TTR and maneuver code.

    ``only`` (bool, rows): refine these rows only; the others keep the scan's lower end
    ``times[lo_idx]``. The groups and the samples each group checks are those of all rows, so
    a refined row gets the value it gets without ``only``. ``group_size``: rows whose ``lo_idx``
    lie in one span of this many samples are refined together, from the earliest one's sample
    on (a larger span: fewer, longer numpy calls; the samples before a row's start follow the
    plan, which does not collide there, so the values do not depend on it).
    """
    q = evasion.scan_step
    code = code.copy()
    lo = np.where(lo_idx >= 0, times[np.maximum(lo_idx, 0)], 0.0)
    hi = times[hi_idx]
    # rows grouped by their lo (about a second each): a group checks from its earliest lo on
    valid = lo_idx >= 0
    for group in np.unique(lo_idx[valid] // group_size):
        members = valid & (lo_idx // group_size == group)
        j0 = int(lo_idx[members].min()) + 1       # the sample after the earliest lo
        refine = np.flatnonzero(members if only is None else members & only)
        if not refine.size:
            continue
        for _ in range(evasion.bisection_steps + (q - 1).bit_length()):
            mid = 0.5 * (lo[refine] + hi[refine])
            ok = avoids(r, refine, mid, j0, times, evasion, lanes)
            can = ok.any(axis=1)
            lo[refine[can]] = mid[can]
            hi[refine[~can]] = mid[~can]
            code[refine[can]] = np.argmax(ok[can], axis=1)
    code[~valid] = -1
    return lo, code
