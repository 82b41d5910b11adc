"""Time-To-React (TTR) risk of highway scenes, after Wagner et al. 2018 [1] as used in [2] II-D.

A *scene* is one time instant: the EGO and one or more traffic objects (TOs), each with position,
speed and heading on a straight road along +x; vehicles may drive in any direction (oncoming,
crossing, reversing, standing: each is predicted in its road frame, see
:func:`~simcred.risk.scene.road_frames`). For every TO a set of predictions (keep lane -- as a
set over its uncertain acceleration --, brake at several levels, change lane, accelerate) with
prior probabilities is checked against the EGO's plan (keep going in its lane). For every
prediction that collides within the horizon, the TTR is the latest time at which an evasive EGO
maneuver (full braking, steering one lane left or right, kickdown) can still start and avoid
that collision. A log-normal reaction-time law maps each TTR to an
accident probability, and the probability-weighted sum over the predictions is the scene's risk.
Everything is batched over scenes: a whole scenario at 10-100 Hz is one call of :func:`risk` or
:func:`risk_series`.

This module builds the plans, predictions and collisions and aggregates the risk; the TTR search
itself (the evasive maneuvers, scan and bisection) is :mod:`simcred.risk.ttr_search`.

References
----------
[1] S. Wagner, K. Groh, T. Kuehbeck, M. Doerfel, A. Knoll, "Using Time-To-React Based on
    Naturalistic Traffic Object Behavior for Scenario-Based Risk Assessment of Automated Driving",
    IEEE Intelligent Vehicles Symposium (IV), 2018, pp. 1521-1528.
[2] Paper 002 (reprocessing pipeline for simulation-based assessment of automated driving),
    section II-D "Risk Assessment".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simcred._json import JsonResult, fields_dict, json_key
from simcred.errors import OptionError, SimcredError
from simcred.risk.prediction import (
    EvasionSet,
    PredictedPath,
    PredictionSet,
    ReactionTime,
    heading_vector,
    lateral_plan,
    rectangles_overlap,
    travel_distance,
)
from simcred.risk.scene import (
    Lanes,
    RoadFrames,
    VehicleStates,
    forward_states,
    road_frames,
)
from simcred.risk.ttr_search import CollidingRows, bisect_ttr, scan_ttr

# work arrays of one chunk of scenes (and of a block of TTR search starts) hold at most about this
# many samples
_CHUNK_SAMPLES = 1 << 16
# max_risk's chunks: larger (fewer numpy calls on the small arrays of its pruned phases; about
# 2 MB per work array)
_MAX_RISK_SAMPLES = 1 << 18
# max_risk scans the colliding predictions by tiers of prior probability: >= 0.01, >= 0.001, the
# rest (a scene pruned on its likely predictions never scans its unlikely ones)
_TIERS = (0.01, 0.001)
# max_risk assesses every coarse²-th scene in full and the other coarse ones against their floor
# (False: every coarse-th in full, as before issue 24; the same values either way)
_NESTED_COARSE = True


@dataclass(frozen=True, slots=True, eq=False, kw_only=True)
class RiskResult(JsonResult):
    """Risk of many scenes, with the per-prediction TTRs it is made of.

    Attributes
    ----------
    risk : ndarray, shape (scenes,)
        Accident probability of the scene, ``1 - Π_o (1 - risk_per_object[:, o])``.
    risk_per_object : ndarray, shape (scenes, objects)
        ``Σ_i p_i g(TTR_i)`` over the predictions of one TO ([1], [2] II-D).
    contribution : ndarray, shape (scenes, objects, predictions)
        The terms ``p_i g(TTR_i)``.
    ttr : ndarray, shape (scenes, objects, predictions)
        TTR (s) per prediction: inf if the plan does not collide within the horizon, 0 if no
        maneuver started now avoids the collision.
    maneuver : ndarray of int, shape (scenes, objects, predictions)
        Index into ``maneuver_names`` of a maneuver that avoids the collision when started at the
        TTR; -1 where the TTR is inf, or 0 because no maneuver started now avoids it.
    collision_time : ndarray, shape (scenes, objects, predictions)
        First sampled time (s) at which the plan collides with the prediction, inf if none.
    ttr_min : ndarray, shape (scenes,)
        Smallest TTR over objects and predictions.
    dominant_object, dominant_prediction : ndarray of int, shape (scenes,)
        The (object, prediction) with the largest contribution; -1 where the risk is 0.
    prediction_names, maneuver_names : tuple of str
        Labels of the prediction and maneuver axes; the prediction axis is the expanded set
        (:meth:`PredictionSet.expanded`: "keep" as ``keep[<offset>]`` quadrature nodes).
    resolution : float
        Search resolution of the TTR (s): ``dt / 2**bisection_steps``.
    predictions, evasion, lanes, reaction
        The configuration that produced the result.
    method : str
        ``"ttr"``: Time-To-React after [1].
    """

    # in to_dict's order (fields_dict): the settings, then per scene: risk, smallest TTR,
    # dominant (object, prediction); the per-prediction arrays and the configuration left out
    method: str = "ttr"
    resolution: float
    prediction_names: tuple[str, ...]
    maneuver_names: tuple[str, ...]
    risk: np.ndarray
    ttr_min: np.ndarray
    dominant_object: np.ndarray
    dominant_prediction: np.ndarray
    risk_per_object: np.ndarray = field(metadata=json_key(None))
    contribution: np.ndarray = field(metadata=json_key(None))
    ttr: np.ndarray = field(metadata=json_key(None))
    maneuver: np.ndarray = field(metadata=json_key(None))
    collision_time: np.ndarray = field(metadata=json_key(None))
    predictions: PredictionSet = field(metadata=json_key(None))
    evasion: EvasionSet = field(metadata=json_key(None))
    lanes: Lanes = field(metadata=json_key(None))
    reaction: ReactionTime = field(metadata=json_key(None))

    def __repr__(self) -> str:
        scenes, objects, predictions = self.ttr.shape
        peak = f"{self.risk.max():.3g}" if self.risk.size else "-"
        return (f"RiskResult({scenes} scenes, {objects} objects, {predictions} predictions, "
                f"max risk {peak})")

    def to_dict(self) -> dict[str, Any]:
        return fields_dict(self)

    @property
    def dominant_maneuver(self) -> np.ndarray:
        """Maneuver code of the dominant (object, prediction); -1 where there is none."""
        scenes = np.arange(self.risk.shape[0])
        o, p = np.maximum(self.dominant_object, 0), np.maximum(self.dominant_prediction, 0)
        return np.where(self.dominant_object >= 0, self.maneuver[scenes, o, p], -1)


# -- the scenes: the EGO's plan, the TOs' predictions, their collisions --------------------------


def _plan(e: dict[str, np.ndarray], predictions: PredictionSet, lanes: Lanes
          ) -> dict[str, Any]:
    """The EGO's plan (scenes, T) in its road frame: its current acceleration along its
    reference lane ([1]). ``x0`` is its local x, ``frame`` its road frame."""
    frame, e = road_frames(forward_states(e), lanes, predictions.lane_heading_limit)
    e = {k: v[:, None] for k, v in e.items()}                           # (S, 1)
    v0 = e["v"] * np.cos(e["heading"])
    xi, speed = travel_distance(v0, e["acceleration"], predictions.times)       # (S, T)
    path = lateral_plan(e, frame.centre[:, None], np.zeros(1), predictions, lanes)
    y, slope = path.at(xi)
    return dict(xi=xi, speed=speed, y=y, slope=slope, path=path, v0=v0, a0=e["acceleration"],
                half=(0.5 * e["length"], 0.5 * e["width"]), x0=e["x"][:, 0], frame=frame)


def _predict(o: dict[str, np.ndarray], plan: dict[str, Any],
             predictions: PredictionSet, lanes: Lanes) -> tuple[np.ndarray, ...]:
    """TO rectangles of every prediction in the EGO's road frame, (S, O, P, T): x relative to
    the EGO's local x at the scene, y, and the heading's cos and sin ([1] predictions).

    ``o`` holds world states with x relative to the EGO's; each TO moves in its own road
    frame, and its rectangles are turned into the EGO's.
    """
    levels = np.array([np.nan if p.acceleration is None else p.acceleration
                       for p in predictions.predictions])
    offsets = np.array([p.acceleration_offset for p in predictions.predictions])
    shift = np.array([p.lane_change for p in predictions.predictions], dtype=float)
    frame, o = road_frames(forward_states(o), lanes, predictions.lane_heading_limit)
    o = {k: v[:, :, None] for k, v in o.items()}                       # (S, O, 1)
    current = np.clip(o["acceleration"], *predictions.acceleration_bounds)
    accel = np.where(np.isnan(levels), current + offsets, levels)      # (S, O, P)
    xi = travel_distance((o["v"] * np.cos(o["heading"]))[..., None], accel[..., None],
                 predictions.times)[0]                                  # (S, O, P, T)
    path = lateral_plan(o, frame.centre[:, :, None], shift, predictions, lanes)
    path = PredictedPath(path.y0[..., None], tuple(b[..., None] for b in path.b),
                         path.length[..., None])
    y, slope = path.at(xi)
    x, (cos, sin) = o["x"][..., None] + xi, heading_vector(slope)
    ego: RoadFrames = plan["frame"]
    for f, to in ((RoadFrames(*(a[:, :, None, None] for a in (frame.cos, frame.sin, frame.centre))),
                   "to_world"),
                  (RoadFrames(*(a[:, None, None, None] for a in (ego.cos, ego.sin, ego.centre))),
                   "to_local")):
        if _identity(f):    # along +x (the usual case): x·1 ∓ y·0 = x exactly, skipped
            continue
        x, y = getattr(f, to)(x, y)
        cos, sin = getattr(f, to)(cos, sin)
    return (x - plan["x0"][:, None, None, None], y, cos, sin)


def _identity(frame: RoadFrames) -> bool:
    """Every frame along +x (rotation by 0: turning into or out of it changes no number but
    the sign of a zero)."""
    return bool((frame.cos == 1.0).all() and (frame.sin == 0.0).all())


def _take(a: np.ndarray, shape: tuple[int, ...], sel: np.ndarray) -> np.ndarray:
    """Rows ``sel`` of ``a`` broadcast to ``shape`` (S, O, P, n) and flattened to (rows, n)."""
    return np.broadcast_to(a, shape).reshape(-1, shape[-1])[sel]


def _scene_risk(ttr: np.ndarray, probabilities: np.ndarray, reaction: ReactionTime
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Contributions (S, O, P), risk per object (S, O) and per scene (S,) of TTRs (S, O, P).

    Monotone: TTRs no larger element by element give risks no smaller (in floating point too:
    every step is a monotone, rounded operation)."""
    contribution = probabilities * reaction.accident_probability(ttr)
    per_object = contribution.sum(axis=-1)
    with np.errstate(divide="ignore"):                  # log1p(-1) = -inf: a certain accident
        total = 0.0 - np.expm1(np.log1p(-np.minimum(per_object, 1.0)).sum(axis=-1))  # no -0.0
    return contribution, per_object, total


def _chunk(ego: dict[str, np.ndarray], obj: dict[str, np.ndarray], predictions: PredictionSet,
           evasion: EvasionSet, lanes: Lanes, floor: float | None = None,
           reaction: ReactionTime | None = None, work_samples: int = _CHUNK_SAMPLES
           ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """TTR, maneuver code and planned collision time (scenes, objects, predictions).

    ``floor`` (with ``reaction``; a number or one per scene): only scenes whose risk can reach
    their ``floor`` are searched in
    full; in the others the TTRs are lower bounds (0 before the scan, the scan's lower end
    after it) whose risk is an upper bound below ``floor``, and the codes are those of the
    scan (or -1). Used by :func:`max_risk`."""
    times = predictions.times
    x_ego = ego["x"]                       # lanes run along x: work relative to the EGO's x
    plan = _plan({**ego, "x": np.zeros_like(x_ego)}, predictions, lanes)
    to = _predict({**obj, "x": obj["x"] - x_ego[:, None]}, plan, predictions, lanes)
    to_half = (0.5 * obj["length"][..., None, None], 0.5 * obj["width"][..., None, None])
    ego_rect = tuple(a[:, None, None, :] for a in (plan["xi"], plan["y"],
                                                   *heading_vector(plan["slope"])))
    hit = rectangles_overlap(ego_rect + tuple(h[..., None, None] for h in plan["half"]),
                             to + to_half)
    collides = hit.any(axis=-1)                                          # (S, O, P)
    first = np.where(collides, np.argmax(hit, axis=-1), times.size)
    collision_time = np.where(collides, times[np.minimum(first, times.size - 1)], np.inf)
    ttr = np.where(collides, 0.0, np.inf)                               # first == 0: TTR 0
    code = np.full(collides.shape, -1)
    searched = collides & (first > 0)
    if floor is not None:      # TTRs 0: the largest risk each scene can have
        floor = np.broadcast_to(np.asarray(floor, dtype=float), collides.shape[:1])
        bound = _scene_risk(ttr, predictions.probabilities, reaction)[2]
        searched &= (bound >= floor)[:, None, None]
    sel = np.flatnonzero(searched)
    if sel.size:
        scene = sel // (collides.shape[1] * collides.shape[2])
        path = plan["path"]
        rows = CollidingRows(
            to=tuple(_take(a, hit.shape, sel) for a in to),
            to_half=tuple(_take(h, (*collides.shape, 1), sel) for h in to_half),
            ego_x=plan["xi"][scene], ego_y=plan["y"][scene], ego_slope=plan["slope"][scene],
            ego_speed=plan["speed"][scene], ego_v0=plan["v0"][scene], ego_a0=plan["a0"][scene],
            ego_path=PredictedPath(path.y0[scene], tuple(b[scene] for b in path.b),
                                   path.length[scene]),
            ego_half=tuple(h[scene] for h in plan["half"]),
        )
        found, found_code = _search(rows, sel, first.ravel()[sel], ttr, floor, predictions,
                                    evasion, lanes, reaction, work_samples)
        np.put(ttr, sel, found)
        np.put(code, sel, found_code)
    return ttr, code, collision_time


def _search(rows: CollidingRows, sel: np.ndarray, first: np.ndarray, ttr: np.ndarray,
            floor: np.ndarray | None, predictions: PredictionSet, evasion: EvasionSet,
            lanes: Lanes, reaction: ReactionTime | None, work_samples: int
            ) -> tuple[np.ndarray, np.ndarray]:
    """TTR and maneuver code of the colliding rows ``sel`` (flat indices into ``ttr``, whose
    other entries are final; ``ttr`` is used as work space).

    With ``floor``, rows are scanned by tiers of prior probability (:data:`_TIERS`): a scene
    whose bound falls below its floor while its likely predictions are scanned (the unlikely
    ones counted at TTR 0) never scans the unlikely ones. Every scene that can still reach its
    floor is scanned in full, tier after tier, and bisected, so its TTRs are those without
    tiers (a row's scan does not depend on the others')."""
    times = predictions.times
    if floor is None:
        lo_idx, hi_idx, code = scan_ttr(rows, first, times, evasion, lanes,
                                        work_samples=work_samples)
        return bisect_ttr(rows, lo_idx, hi_idx, code, times, evasion, lanes)
    scene_of = sel // (ttr.size // ttr.shape[0])

    def reachable(lo_idx: np.ndarray) -> np.ndarray:
        """Rows whose scene's risk, with the TTRs' lower ends ``lo_idx``, reaches floor."""
        np.put(ttr, sel, np.where(lo_idx >= 0, times[np.maximum(lo_idx, 0)], 0.0))
        return (_scene_risk(ttr, predictions.probabilities, reaction)[2] >= floor)[scene_of]

    probability = predictions.probabilities[sel % ttr.shape[-1]]
    tier = np.searchsorted(-np.asarray(_TIERS), -probability)
    lo_idx, hi_idx, code = np.full(sel.size, -1), first.copy(), np.full(sel.size, -1)
    for k in range(len(_TIERS) + 1):
        scan = np.flatnonzero(tier == k)
        scan = scan[reachable(lo_idx)[scan]]
        if not scan.size:
            continue
        mine = np.zeros(sel.size, dtype=bool)
        mine[scan] = True

        def prune(lo: np.ndarray, mine: np.ndarray = mine, before: np.ndarray = lo_idx
                  ) -> np.ndarray:
            return reachable(np.where(mine, lo, before))

        lo, hi, got = scan_ttr(rows, first, times, evasion, lanes, work_samples=work_samples,
                               rows=scan, prune=prune)
        lo_idx, hi_idx, code = (np.where(mine, new, old) for new, old in
                                ((lo, lo_idx), (hi, hi_idx), (got, code)))
    # the few rows still reachable are refined as one group (fewer numpy calls)
    return bisect_ttr(rows, lo_idx, hi_idx, code, times, evasion, lanes,
                      only=reachable(lo_idx), group_size=times.size)


# -- public API ----------------------------------------------------------------------------------


# Long only by its numpydoc docstring (with the deviations from [1]); the code is ~25 lines.
def risk(ego: VehicleStates, objects: VehicleStates, *,
         predictions: PredictionSet | None = None, evasion: EvasionSet | None = None,
         lanes: Lanes | None = None, reaction: ReactionTime | None = None) -> RiskResult:
    """Accident risk of many highway scenes from Time-To-React, after Wagner et al. 2018 [1].

    Parameters
    ----------
    ego : VehicleStates
        The EGO in every scene, shape (scenes,).
    objects : VehicleStates
        The TOs, shape (scenes,) for one per scene or (scenes, objects).
    predictions : PredictionSet, default: PredictionSet()
        TO predictions, priors, horizon and time step.
    evasion : EvasionSet, default: EvasionSet()
        Evasive EGO maneuvers and the TTR resolution.
    lanes : Lanes, default: Lanes()
        Lane geometry (width 3.5 m, a lane centre at y = 0).
    reaction : ReactionTime, default: ReactionTime()
        Maps a TTR to an accident probability g(TTR).

    Returns
    -------
    RiskResult
        ``risk`` (scenes,), ``ttr`` (scenes, objects, predictions), ``ttr_min``, the dominant
        object/prediction/maneuver and the planned collision times.

    Notes
    -----
    Follows [1] as summarised in [2] II-D: predictions per TO, checked against the EGO's plan;
    evasion trajectories give the TTR; probability-weighted g(TTR) give the risk. Deviations
    (details in docs/risk.md):

    - predictions are closed-form point-mass trajectories with fixed priors
      (:data:`DEFAULT_PREDICTIONS`), not the euroFOT statistics of [1]; g is a log-normal
      reaction-time survival function, a stand-in for the mapping of [1];
    - collisions are sampled every ``dt`` within the horizon only: a maneuver that merely
      postpones a collision past the horizon counts as avoiding it;
    - an evasive maneuver is checked against the one predicted TO trajectory it evades (not
      against other TOs or road edges); braking and kickdown are instantaneous, steering does
      not brake;
    - crossing and turning traffic is predicted straight on in its own frame (no junctions);
    - TOs are combined as independent: risk = 1 - Π_o (1 - risk_o).

    Cost: about 1.5 ms per scene for one TO with the defaults on a cut-in (docs/risk.md); it
    grows with ``(horizon / dt)²`` for every prediction that collides.

    Examples
    --------
    >>> ego = VehicleStates(x=[0.0, 0.0], y=0.0, v=27.8, heading=0.0, name="ego")
    >>> lead = VehicleStates(x=[30.0, 150.0], y=0.0, v=20.0, heading=0.0, name="to")
    >>> result = risk(ego, lead)
    >>> result.prediction_names[4:7]
    ('keep[-0.93]', 'keep[+0.00]', 'keep[+0.93]')
    >>> result.ttr[0, 0, 4:7].round(2)    # keep: the lead's acceleration 0 ± quadrature nodes
    array([2.13, 2.78, 4.22])
    >>> result.risk.round(4), result.prediction_names[result.dominant_prediction[0]]
    (array([0.0614, 0.    ]), 'brake-2')
    """
    predictions, evasion, lanes, reaction, e, o = _risk_iv(ego, objects, predictions, evasion,
                                                           lanes, reaction)
    nodes = predictions.expanded()
    n_scenes, n_obj = o["x"].shape
    n_pred = len(nodes.predictions)
    per_chunk = max(1, _CHUNK_SAMPLES // (n_obj * n_pred * nodes.times.size))
    parts = [_chunk({k: v[i:i + per_chunk] for k, v in e.items()},
                    {k: v[i:i + per_chunk] for k, v in o.items()}, nodes, evasion, lanes)
             for i in range(0, n_scenes, per_chunk)]
    ttr, code, collision_time = (np.concatenate(a) for a in zip(*parts, strict=True))
    contribution, per_object, total = _scene_risk(ttr, nodes.probabilities, reaction)
    flat = contribution.reshape(n_scenes, -1)
    best = np.argmax(flat, axis=1)
    none = flat[np.arange(n_scenes), best] <= 0
    return RiskResult(
        risk=total, risk_per_object=per_object, contribution=contribution, ttr=ttr,
        maneuver=code, collision_time=collision_time,
        ttr_min=ttr.reshape(n_scenes, -1).min(axis=1),
        dominant_object=np.where(none, -1, best // n_pred),
        dominant_prediction=np.where(none, -1, best % n_pred),
        prediction_names=nodes.names, maneuver_names=evasion.maneuvers,
        resolution=predictions.dt / 2 ** evasion.bisection_steps,
        predictions=predictions, evasion=evasion, lanes=lanes, reaction=reaction,
    )


def max_risk(ego: VehicleStates, objects: VehicleStates, *,
             predictions: PredictionSet | None = None, evasion: EvasionSet | None = None,
             lanes: Lanes | None = None, reaction: ReactionTime | None = None,
             coarse: int = 5, sizes: Sequence[int] | None = None) -> float | np.ndarray:
    """``risk(...).risk.max()`` (the same value), searching only the scenes that can hold it.

    Every ``coarse``-th scene is assessed in full first; its largest risk is a floor, raised
    by the neighbours of the riskiest of them (a risk peak can be one scene wide). The other
    scenes are then skipped where their risk cannot reach the floor: before the TTR search
    when the probabilities of their colliding predictions (TTR 0) stay below it, during the
    scan and before the bisection when the TTRs' lower ends found so far do. The scenes
    assessed in full get the values :func:`risk` gives them (the TTR of a row depends on its
    own scene only), so the maximum is :func:`risk`'s, not an approximation (tested, also on
    the variation campaign).

    ``sizes``: the scenes are consecutive groups of these sizes (say, the runs of a campaign,
    assessed in one call); the result is then each group's maximum, an array.
    """
    predictions, evasion, lanes, reaction, e, o = _risk_iv(ego, objects, predictions, evasion,
                                                           lanes, reaction)
    if not (isinstance(coarse, int) and coarse >= 1):
        raise OptionError(f"coarse must be an integer >= 1, got {coarse!r}")
    n_scenes, n_obj = o["x"].shape
    counts = np.array([n_scenes] if sizes is None else list(sizes), dtype=int)
    if counts.ndim != 1 or counts.size == 0 or (counts < 1).any() or counts.sum() != n_scenes:
        raise OptionError(f"sizes must be >= 1 each and add up to the {n_scenes} scenes")
    nodes = predictions.expanded()
    per_chunk = max(1, _MAX_RISK_SAMPLES // (n_obj * len(nodes.predictions) * nodes.times.size))
    group = np.repeat(np.arange(counts.size), counts)
    local = np.arange(n_scenes) - np.concatenate([[0], np.cumsum(counts)[:-1]])[group]

    def risks(scenes: np.ndarray, floor: np.ndarray | None) -> np.ndarray:
        """Risks of ``scenes``: exact, or upper bounds below their ``floor``."""
        parts = [np.zeros(0)]
        for i in range(0, scenes.size, per_chunk):
            take = scenes[i:i + per_chunk]
            ttr = _chunk({k: v[take] for k, v in e.items()}, {k: v[take] for k, v in o.items()},
                         nodes, evasion, lanes, reaction=reaction, work_samples=_MAX_RISK_SAMPLES,
                         floor=None if floor is None else floor[i:i + per_chunk])[0]
            parts.append(_scene_risk(ttr, nodes.probabilities, reaction)[2])
        return np.concatenate(parts)

    # every coarse²-th scene in full (every group's first scene among them), the other coarse
    # ones against their floor: pruned ones stay below it, so the riskiest is exact
    full = coarse * coarse if _NESTED_COARSE else coarse
    done = np.flatnonzero(local % full == 0)
    best = np.full(counts.size, -np.inf)
    found = risks(done, None)
    np.maximum.at(best, group[done], found)
    more = np.flatnonzero((local % coarse == 0) & (local % full != 0))
    if more.size:
        found = np.concatenate([found, risks(more, best[group[more]])])
        done = np.concatenate([done, more])
        np.maximum.at(best, group[done], found)
    top = np.zeros(counts.size, dtype=int)             # the riskiest coarse scene of each group
    order = np.lexsort((-found, group[done]))
    firsts = order[np.r_[True, np.diff(group[done][order]) > 0]]
    top[group[done][firsts]] = local[done][firsts]
    near = (np.abs(local - top[group]) < coarse) & (local % coarse != 0)
    for scenes in (np.flatnonzero(near), np.flatnonzero(~near & (local % coarse != 0))):
        if scenes.size:
            np.maximum.at(best, group[scenes], risks(scenes, best[group[scenes]]))
    return float(best[0]) if sizes is None else best


def _risk_iv(ego: Any, objects: Any, predictions: Any, evasion: Any, lanes: Any, reaction: Any
             ) -> tuple[PredictionSet, EvasionSet, Lanes, ReactionTime,
                        dict[str, np.ndarray], dict[str, np.ndarray]]:
    """Validate and normalise the arguments of :func:`risk`."""
    configs = []
    for name, value, cls in (("predictions", predictions, PredictionSet),
                             ("evasion", evasion, EvasionSet), ("lanes", lanes, Lanes),
                             ("reaction", reaction, ReactionTime)):
        value = cls() if value is None else value
        if not isinstance(value, cls):
            raise OptionError(f"{name} must be a {cls.__name__}, got {type(value).__name__}")
        configs.append(value)
    for name, value in (("ego", ego), ("objects", objects)):
        if not isinstance(value, VehicleStates):
            raise SimcredError(f"{name} must be VehicleStates, got {type(value).__name__}")
    if ego.x.ndim > 1:
        raise SimcredError(f"ego states must be 1-D (scenes,), got shape {ego.shape}")
    e = {k: np.atleast_1d(v) for k, v in ego.as_dict().items()}
    shape = {0: (1, 1), 1: (*objects.shape, 1), 2: objects.shape}[len(objects.shape)]
    o = {k: v.reshape(shape) for k, v in objects.as_dict().items()}
    if o["x"].shape[0] != e["x"].shape[0]:
        raise SimcredError(f"{objects.name} has {o['x'].shape[0]} scenes, ego has "
                           f"{e['x'].shape[0]}")
    if o["x"].shape[1] == 0 or e["x"].shape[0] == 0:
        raise SimcredError("need at least one scene and one object")
    return (*configs, e, o)
