"""The variation campaign as it was before issue 24 point 6, for benchmarks/vary.py: reference
copies of the functions that changed, patched in for the duration of :func:`before_path`.

What it restores: 11 "keep" nodes; the brake/kickdown check without its longitudinal prefilter;
the scan evaluating starts past the planned collision; the colliding predictions scanned all
together (no tiers); frames along +x turned; every coarse scene assessed in full; bisection
groups of 10 samples; the refit's local accelerations one window at a time; tasks (and
resimulation batches) of 50 variations in-process too; and no caches of the refit and the
resimulation's sampling (:func:`without_caches`). The maxima are the same as now with 11 nodes
(the benchmark checks it).

:func:`without_caches` alone is the campaign as it was just before the refit caches (issue 24,
the refit and resimulation speed-ups: docs/benchmarks.md): bases, quadratures, pseudo-inverses,
least-squares splines, plausibility rates and object states computed anew at every call (their
uncached code paths, the same numbers).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import replace

import numpy as np

import simcred.risk.ttr as ttr_module
import simcred.risk.ttr_search as search_module
import simcred.scenario.description as description_module
import simcred.scenario.fit_constraints as constraints_module
import simcred.scenario.fit_robust as robust_module
import simcred.scenario.fit_support as support_module
import simcred.scenario.plausibility as plausibility_module
import simcred.scenario.spline as spline_module
from simcred.reprocess.vary import AUTO_CHUNK_SIZE, VaryConfig
from simcred.risk import PredictionSet
from simcred.risk.prediction import PredictedPath, heading_vector, rectangles_overlap
from simcred.risk.prediction import travel_distance as travel


def hits_longitudinal_before(r, idx, start, j0, times, name, evasion):
    """Brake/kickdown check: the lateral path, heading and rectangle test on every row."""
    t, s = times[j0:], start[:, None]
    xi_s, v_s = travel(r.ego_v0[idx], r.ego_a0[idx], s)
    since = np.maximum(t - s, 0.0)
    if name == "brake":
        distance = travel(v_s, evasion.brake_acceleration, since)[0]
    else:
        distance = evasion.kickdown_travel(v_s, since)[0]
    xi = np.where(t > s, xi_s + distance, r.ego_x[idx, j0:])
    path = PredictedPath(r.ego_path.y0[idx], tuple(b[idx] for b in r.ego_path.b),
                         r.ego_path.length[idx])
    y, slope = path.at(xi)
    to = tuple(a[idx, j0:] for a in r.to) + tuple(a[idx] for a in r.to_half)
    half = (r.ego_half[0][idx], r.ego_half[1][idx])
    return rectangles_overlap((xi, y, *heading_vector(slope), *half), to).any(axis=1)


def scan_before(r, first, times, evasion, lanes, *, work_samples, prune=None, rows=None):
    """The scan, evaluating every start of a block (also those past the planned collision)."""
    q = evasion.scan_step
    lo_idx, hi_idx, code = np.full(first.size, -1), first.copy(), np.full(first.size, -1)
    active = np.arange(first.size) if rows is None else np.asarray(rows)
    k = 0
    while active.size:
        work = active.size * (times.size - k) * len(evasion.maneuvers)
        block = int(np.clip(work_samples // max(work, 1), 1, (times.size - 2 - k) // q + 1))
        index = k + q * np.arange(block)
        ok = search_module.avoids(r, np.repeat(active, block),
                                  np.tile(times[index], active.size), k + 1, times, evasion,
                                  lanes)
        can = ok.any(axis=1).reshape(active.size, block)
        codes = np.argmax(ok, axis=1).reshape(active.size, block)
        ends = np.where(can.all(axis=1), block, np.argmin(can, axis=1))
        has = ends > 0
        last = np.maximum(ends - 1, 0)
        code[active[has]] = codes[has, last[has]]
        lo_idx[active[has]] = index[last[has]]
        stopped = ends < block
        hi_idx[active[stopped]] = np.minimum(index[ends[stopped]], first[active[stopped]])
        active = active[~stopped]
        k += q * block
        active = active[first[active] > k]
        if prune is not None and active.size:
            active = active[prune(lo_idx)[active]]
    return lo_idx, hi_idx, code


def bisect_before(*args, group_size=None, **kwargs):
    """The bisection with its groups of 10 samples."""
    return search_module.bisect_ttr(*args, **kwargs)


_NO_CACHES = ((spline_module, "_CACHED_VALUES", -1), (robust_module, "_CACHED_SAMPLES", -1),
              (support_module, "_CACHED_SAMPLES", -1), (description_module, "_CACHED_STATES", -1),
              (constraints_module, "_CACHED_GRID", -1),
              (plausibility_module, "_default_rates",
               plausibility_module._default_rates.__wrapped__))


@contextmanager
def _patched(patches):
    saved = [(module, name, getattr(module, name)) for module, name, _ in patches]
    for module, name, value in patches:
        setattr(module, name, value)
    try:
        yield
    finally:
        for module, name, value in saved:
            setattr(module, name, value)


@contextmanager
def without_caches():
    """The refit and the resimulation's sampling without their caches (every size above the
    cached ones' limits; the plausibility rates sampled anew)."""
    with _patched(_NO_CACHES):
        yield


@contextmanager
def before_path(config: VaryConfig):
    """Yields ``config`` with 11 nodes and tasks of 50 variations (in-process too); in this
    process the code paths above are patched in."""
    patches = ((search_module, "_hits_longitudinal", hits_longitudinal_before),
               (ttr_module, "scan_ttr", scan_before), (ttr_module, "bisect_ttr", bisect_before),
               (ttr_module, "_TIERS", ()), (ttr_module, "_identity", lambda frame: False),
               (ttr_module, "_NESTED_COARSE", False),
               (support_module, "local_acceleration", support_module._local_acceleration_loop))
    with _patched(patches + _NO_CACHES):
        yield replace(config, predictions=PredictionSet(), chunk_size=AUTO_CHUNK_SIZE)
