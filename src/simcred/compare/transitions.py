"""From runs to the response data of a conditional comparison: state, covariates, response.

For every transition ``t → t+1`` inside a run:

* the **state** is the discretised state at ``t`` (pooled equal-frequency bins of every feature,
  exogenous inputs included; history and time windows as in :mod:`simcred.compare.encoding`);
* the **covariates** are the continuous feature values at ``t`` and, for declared inputs, their
  values at ``t+1`` (the input path is given, not produced by the model);
* the **response** is the rate of change ``(y[t+1] − y[t]) / Δt`` of every feature that is not
  an input: what the model does in that situation, in the feature's unit per second.

The response is then **adjusted**: a pooled global cubic fit on the covariates, then within each
state a pooled quadratic fit on what is left (``residual = response − fit``; both fits use both
sets together and no labels, so the permutation null is untouched). Two sets that visit a bin in
different places (other leaders, shorter runs, a start transient) then no longer differ for that
reason alone, and a level or a change of level give the same residual. States with too few
pooled transitions for a fit of their own are centred on their pooled mean.

The chain test uses these residuals. The **effect** (:mod:`simcred.compare.effect`) uses the
response after the global fit only (:attr:`Transitions.effect_residual`): a state's own fit, with
5–15 coefficients on 25–150 of its transitions, absorbs part of the A–B difference by chance, and
the more states get a fit the more it absorbs, so the effect's estimate fell with the sample size
(14–17 % low at 160 pairs). The global fit has a few dozen coefficients against every transition
of both sets; a per-state offset does not change a difference of means or of spreads. Fits
cross-fitted over folds of the units were tried and dropped (docs/calibration.md).
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from simcred.compare.scratch import std_columns
from simcred.compare.threads import in_threads
from simcred.errors import OptionError

#: Pooled transitions per fitted coefficient before a state gets its linear adjustment.
PER_COEFFICIENT = 5
#: Largest condition number of the unit-diagonal Gram matrix solved by the normal equations
#: (coefficients then good to ~1e-8, far below the comparison's resolution); beyond it an SVD.
NORMAL_EQUATIONS_CONDITION = 1e8
#: Rows of a fit's design matrix built at once (≈ 20 MB for the global cubic fit's 10 columns).
FIT_ROWS = 2**18


@dataclass(frozen=True, slots=True, eq=False)
class Transitions:
    """Pooled transitions of both sets, sorted by (state, unit).

    ``state``: state code at ``t``; ``unit``: the design unit of the transition's run;
    ``residual``: (n, J) adjusted response in the response features' units per second (global
    and per-state fits: the chain test's); ``level``: the response after the global fit only
    (the effect's; None: not computed, ``residual`` serves); ``profile``: (distinct states, J)
    per state the pooled mean of the global fit, i.e. how the model responds there on average
    (label-free; the response test's profile contrasts; None: not computed); ``fit``: the
    global fit as the effect's fit influence needs it (:class:`GlobalFit`; None: not kept, the
    effect's bootstrap holds the fit fixed).
    """

    state: np.ndarray
    unit: np.ndarray
    residual: np.ndarray
    response: tuple[str, ...]
    spread: np.ndarray | None = None  # pooled standard deviation of the raw response rates
    level: np.ndarray | None = None
    profile: np.ndarray | None = None
    fit: GlobalFit | None = None

    @property
    def effect_residual(self) -> np.ndarray:
        """The adjusted response the effect is estimated from (module docs)."""
        return self.residual if self.level is None else self.level


def response_features(features: Sequence[str], inputs: Sequence[str]) -> tuple[str, ...]:
    """The features the model produces (all but the inputs); one-line error if none is left."""
    unknown = [name for name in inputs if name not in features]
    if unknown:
        raise OptionError(f"input {unknown[0]!r} is not one of the features {list(features)}; "
                          "inputs condition the state, so they must be features")
    out = tuple(name for name in features if name not in set(inputs))
    if not out:
        raise OptionError("every feature is declared an input: nothing of the model's own "
                          "response is left to compare")
    return out


def transitions(parts: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
                unit_of_run: np.ndarray, features: Sequence[str], inputs: Sequence[str],
                history: int) -> Transitions:
    """Pool the transitions of both sets.

    ``parts``: per set, ``(values, time, offsets, codes)`` with ``codes`` the encoded states
    (one per row from step ``history - 1`` of each run on); ``unit_of_run``: the unit of every
    pooled run (A's runs first).
    """
    response = response_features(features, inputs)
    out_j = [features.index(name) for name in response]
    in_j = [features.index(name) for name in inputs]
    pieces = [_set_index(time, offsets, codes, history) for _, time, offsets, codes in parts]
    state = np.concatenate([p[0] for p in pieces])
    first_run = np.cumsum([0] + [len(offsets) - 1 for _, _, offsets, _ in parts])
    run = np.concatenate([p[1] + first_run[i] for i, p in enumerate(pieces)])
    unit = np.asarray(unit_of_run)[run]
    del run
    order = _order(state, unit)
    state, unit = np.take(state, order), np.take(unit, order)
    covariates, rate = _sorted_columns([p[0] for p in parts], [p[2:] for p in pieces], order,
                                       out_j, in_j)
    scratch = np.empty_like(rate)  # the spread's squared deviations, then the residual
    spread = std_columns(rate, scratch)
    runs_a = first_run[1]
    units_a = int(np.asarray(unit_of_run)[:runs_a].max()) + 1 if runs_a else 0
    level, fit = global_fit(covariates, rate, state, unit >= units_a)
    residual = per_state_residual(state, covariates, level, out=scratch)
    return Transitions(state, unit, residual, response, spread, level,
                       state_means(state, np.subtract(rate, level, out=rate)), fit)


def _sorted_columns(values: Sequence[np.ndarray], where: Sequence[tuple[np.ndarray, np.ndarray]],
                    order: np.ndarray, out_j: list[int], in_j: list[int]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Column-major (transitions, columns) covariates ``[values at t, inputs at t+1]`` and
    response rates ``(y[t+1] − y[t]) / Δt`` of the pooled transitions in ``order``; ``where``:
    per set its transitions' rows ``t`` and ``Δt``. Written column by column into one array
    each, then reordered through one reused column: the per-set, pooled, sorted and
    column-major copies were ~1.2 GB of fresh memory at 8 M transitions."""
    dtype = np.result_type(*values)
    width, n = values[0].shape[1], len(order)
    covariates = np.empty((width + len(in_j), n), dtype)  # transposed: a row is a column
    rate = np.empty((len(out_j), n), np.result_type(dtype, *(dt for _, dt in where)))
    longest = max((len(rows) for rows, _ in where), default=0)
    index, then = np.empty(longest, dtype=np.int64), np.empty(longest, dtype)
    at = 0  # mode="clip" below: the indices are in range, and "raise" buffers ``out``
    for flat, (rows, dt) in zip((np.ravel(v) for v in values), where, strict=True):
        here, k = slice(at, at + len(rows)), len(rows)
        base = rows * width
        for c in range(width):  # values at t
            _gather(flat, base, c, index[:k], covariates[c, here])
        for c, f in enumerate(in_j, start=width):  # inputs at t + 1
            _gather(flat, base, width + f, index[:k], covariates[c, here])
        for r, f in enumerate(out_j):
            _gather(flat, base, width + f, index[:k], then[:k])
            np.subtract(then[:k], covariates[f, here], out=rate[r, here])
            np.divide(rate[r, here], dt, out=rate[r, here])
        at += k
    _reorder(covariates, order)
    _reorder(rate, order)
    return covariates.T, rate.T


def _gather(flat: np.ndarray, base: np.ndarray, offset: int, index: np.ndarray,
            out: np.ndarray) -> None:
    """``out = flat[base + offset]``, the indices formed in ``index`` (both reused buffers)."""
    np.take(flat, np.add(base, offset, out=index), out=out, mode="clip")


def _reorder(rows: np.ndarray, order: np.ndarray) -> None:
    """``rows[:, order]`` in place, row by row through one reused row per thread."""
    spare = threading.local()

    def reorder(r: int) -> None:
        if not hasattr(spare, "row"):
            spare.row = np.empty(rows.shape[1], rows.dtype)
        np.take(rows[r], order, out=spare.row, mode="clip")
        rows[r] = spare.row

    in_threads(reorder, range(rows.shape[0]))


def state_means(state: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(distinct states, columns): the mean of ``values`` over each state's rows (``state``
    sorted)."""
    starts = np.r_[0, np.flatnonzero(np.diff(state)) + 1]
    return np.add.reduceat(values, starts, axis=0) / np.diff(np.r_[starts, len(state)])[:, None]


def _order(state: np.ndarray, unit: np.ndarray) -> np.ndarray:
    """``np.lexsort((unit, state))``: a stable sort by unit (none when already sorted), then a
    stable sort by state (radix sorts where the keys fit 16 bits)."""
    def stable(key: np.ndarray) -> np.ndarray:
        if len(key) and key.min() >= 0 and key.max() < 2**16:
            key = key.astype(np.uint16)
        return np.argsort(key, kind="stable")

    if len(unit) > 1 and (unit[1:] < unit[:-1]).any():
        by_unit = stable(unit)
        return by_unit[stable(state[by_unit])]
    return stable(state)


def _set_index(time, offsets, codes, history):
    """One set's (state, run, row ``t``, ``Δt``) per transition."""
    lengths = np.diff(offsets)
    coded = np.maximum(lengths - (history - 1), 0)  # rows from step history - 1 on: encoded
    kept = np.maximum(coded - 1, 0)  # of those, all but a run's last row start a transition
    has = kept > 0
    mark = np.zeros(len(time) + 1, dtype=np.int8)
    mark[(offsets[:-1] + history - 1)[has]] = 1
    mark[(offsets[1:] - 1)[has]] = -1
    rows = np.flatnonzero(np.cumsum(mark[:-1], dtype=np.int8))
    code_kept = np.ones(len(codes), dtype=bool)  # encode() keeps exactly the coded rows
    code_kept[np.cumsum(coded)[coded > 0] - 1] = False
    state = np.asarray(codes)[code_kept].astype(np.int64, copy=False)
    run = np.repeat(np.arange(len(lengths)), kept)
    dt = time[rows + 1] - time[rows]
    return state, run, rows, dt


def adjusted(state: np.ndarray, covariates: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """Residuals of two pooled least-squares fits of ``rate`` (``state`` sorted): a global cubic
    polynomial in the covariates (sparse states have too few transitions for a fit of their own),
    then per state a quadratic polynomial on what is left (:func:`per_state_residual`)."""
    return per_state_residual(state, covariates, global_residual(covariates, rate))


@dataclass(frozen=True, slots=True, eq=False)
class GlobalFit:
    """The pooled global fit as :mod:`simcred.compare.fit_influence` needs it: the covariates it
    was fitted on (``rows``), its basis (None: the fit is the mean), the Gram matrix ``X'X`` of
    its design rows and, per distinct state (sorted) and side, the sums of those rows."""

    rows: np.ndarray
    basis: Basis | None
    gram: np.ndarray
    column_sums: np.ndarray  # (states, 2, columns)

    def design(self, x: np.ndarray) -> np.ndarray:
        """The design rows of covariates ``x``."""
        return np.ones((len(x), 1)) if self.basis is None else self.basis.design(x)


def global_fit(covariates: np.ndarray, rate: np.ndarray, state: np.ndarray, side: np.ndarray
               ) -> tuple[np.ndarray, GlobalFit]:
    """``rate`` less its pooled global cubic fit (column-major; :func:`global_residual`), and the
    fit (``state`` sorted, ``side`` True for B's transitions)."""
    segment = 2 * np.cumsum(np.r_[False, state[1:] != state[:-1]]) + side
    n_segments = 2 * (int(segment[-1]) // 2 + 1) if len(segment) else 2
    fitted, basis, gram, sums = _fit(covariates, rate, True, segment, n_segments)
    return _less(rate, fitted), GlobalFit(covariates, basis, gram,
                                          sums.reshape(n_segments // 2, 2, -1))


def global_residual(covariates: np.ndarray, rate: np.ndarray) -> np.ndarray:
    """``rate`` less its pooled global cubic fit (column-major)."""
    return _less(rate, _fitted(covariates, rate, cubic=True))


def _less(rate: np.ndarray, fitted: np.ndarray) -> np.ndarray:
    """``rate − fitted``, column-major, written into ``fitted`` where it can be."""
    if fitted.flags.writeable and fitted.flags.f_contiguous:
        return np.subtract(rate, fitted, out=fitted)  # in place: one fresh array fewer
    return np.asfortranarray(rate - fitted)


def per_state_residual(state: np.ndarray, covariates: np.ndarray, rate: np.ndarray,
                       out: np.ndarray | None = None) -> np.ndarray:
    """``rate`` less a pooled fit per state (``state`` sorted): quadratic where the state has
    ``PER_COEFFICIENT`` transitions per coefficient, else linear, else its mean; written into
    ``out`` where given (``rate``'s shape)."""
    residual = np.empty_like(rate) if out is None else out
    bounds = np.r_[0, np.flatnonzero(np.diff(state)) + 1, len(state)]

    def fit(s: int) -> None:
        lo, hi = bounds[s], bounds[s + 1]
        residual[lo:hi] = rate[lo:hi] - _fitted(covariates[lo:hi], rate[lo:hi])

    in_threads(fit, range(len(bounds) - 1))
    return residual


def _fitted(x: np.ndarray, y: np.ndarray, cubic: bool = False) -> np.ndarray:
    """Least-squares polynomial fit of ``y`` on ``x`` (:class:`Basis`; the mean where too few
    rows for a linear fit)."""
    return _fit(x, y, cubic)[0]


def _fit(x: np.ndarray, y: np.ndarray, cubic: bool, segment: np.ndarray | None = None,
         n_segments: int = 0) -> tuple[np.ndarray, Basis | None, np.ndarray, np.ndarray]:
    """:func:`_fitted` with its basis, its Gram matrix and, given a ``segment`` per row, the
    (segments, columns) sums of the design rows. The coefficients come from the normal
    equations where they are well conditioned (one Gram product, 10-20x faster than an SVD on
    millions of rows), else by SVD (collinear terms, e.g. the square of a covariate with two
    values). The design matrix is built :data:`FIT_ROWS` rows at a time (the global fit's would
    be 10 columns × every transition), whole only for the SVD."""
    basis = Basis.of(x, cubic)
    if basis is None:  # the mean: no design to build
        ones = np.ones((len(x), 1))
        sums = np.zeros((n_segments, 1)) if segment is None else \
            _segment_sums(ones, segment, n_segments)
        return np.broadcast_to(y.mean(axis=0), y.shape), None, ones.T @ ones, sums
    design = basis.design
    parts = [slice(lo, lo + FIT_ROWS) for lo in range(0, len(x), FIT_ROWS)] or [slice(0, 0)]
    whole = design(x) if len(parts) == 1 else None  # one chunk: its design built once

    def rows_of(i: int) -> np.ndarray:
        return whole if whole is not None else design(x[parts[i]])

    def products(i: int) -> tuple[np.ndarray, np.ndarray]:
        rows = rows_of(i)
        return rows.T @ rows, rows.T @ y[parts[i]]

    gram, moment = 0.0, 0.0
    for part_gram, part_moment in in_threads(products, range(len(parts))):
        gram, moment = gram + part_gram, moment + part_moment  # in order: the same sums
    coefficients = _normal_equations(gram, moment)
    if coefficients is None:
        coefficients = np.linalg.lstsq(whole if whole is not None else design(x), y,
                                       rcond=None)[0]
    out = np.empty_like(y)

    def fitted(i: int) -> np.ndarray | None:
        rows = rows_of(i)
        out[parts[i]] = rows @ coefficients
        return None if segment is None else _segment_sums(rows, segment[parts[i]], n_segments)

    sums = np.zeros((n_segments, len(gram)))
    for piece in in_threads(fitted, range(len(parts))):
        if piece is not None:
            sums += piece  # in order: the same sums
    return out, basis, gram, sums


def _segment_sums(rows: np.ndarray, segment: np.ndarray, n_segments: int) -> np.ndarray:
    """(segments, columns) sums of ``rows`` per ``segment`` (sorted: each a run of rows)."""
    starts = np.flatnonzero(np.r_[True, segment[1:] != segment[:-1]]) if len(segment) else \
        np.zeros(0, dtype=np.int64)
    out = np.zeros((n_segments, rows.shape[1]))
    if len(starts):
        block = np.stack([np.add.reduceat(column, starts) for column in rows.T], axis=1)
        np.add.at(out, segment[starts], block)
    return out


def _normal_equations(gram: np.ndarray, moment: np.ndarray) -> np.ndarray | None:
    """The solution of ``gram · β = moment`` where the unit-diagonal ``gram`` has a condition
    number ≤ :data:`NORMAL_EQUATIONS_CONDITION`; None else (the caller takes the SVD)."""
    norm = np.sqrt(np.diag(gram))
    if not (norm > 0).all():
        return None
    scaled = gram / np.outer(norm, norm)
    eigen = np.linalg.eigvalsh(scaled)
    if eigen[0] * NORMAL_EQUATIONS_CONDITION <= eigen[-1]:
        return None
    factor = scipy.linalg.cho_factor(scaled)
    return scipy.linalg.cho_solve(factor, moment / norm[:, None]) / norm[:, None]


@dataclass(frozen=True, slots=True, eq=False)
class Basis:
    """``[1, z, z_i z_j (, z_i z_j z_k)]`` of covariates ``z`` standardised on the fit's rows
    (quadratic and cubic terms only with ``PER_COEFFICIENT`` rows per coefficient)."""

    centre: np.ndarray
    scale: np.ndarray
    varying: np.ndarray
    terms: tuple[tuple[int, ...], ...]

    @classmethod
    def of(cls, x: np.ndarray, cubic: bool = False) -> Basis | None:
        """The basis for fit rows ``x``, or None when even a linear fit has too few rows."""
        centre, scale = x.mean(axis=0), x.std(axis=0)
        varying = scale > 0
        n, p = len(x), int(varying.sum())
        if n < PER_COEFFICIENT * (p + 1):
            return None
        terms: list[tuple[int, ...]] = [(i,) for i in range(p)]
        if n >= PER_COEFFICIENT * (1 + p + p * (p + 1) // 2):
            terms += itertools.combinations_with_replacement(range(p), 2)
        if cubic and n >= PER_COEFFICIENT * (1 + p + p * (p + 1) // 2
                                             + p * (p + 1) * (p + 2) // 6):
            terms += itertools.combinations_with_replacement(range(p), 3)
        return cls(centre[varying], scale[varying], varying, tuple(terms))

    def design(self, x: np.ndarray) -> np.ndarray:
        """(rows, 1 + terms) design matrix of ``x``."""
        z = (x[:, self.varying] - self.centre) / self.scale
        columns = [np.ascontiguousarray(z[:, i]) for i in range(z.shape[1])]
        out = np.empty((len(x), 1 + len(self.terms)), order="F" if len(columns) > 1 else "C")
        out[:, 0] = 1.0
        for c, term in enumerate(self.terms, start=1):
            column = out[:, c]
            if len(term) == 1:
                column[:] = columns[term[0]]
                continue
            np.multiply(columns[term[0]], columns[term[1]], out=column)
            for k in term[2:]:  # left to right, as z_i * z_j * z_k
                column *= columns[k]
        return out
