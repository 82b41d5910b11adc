"""From runs to state codes: pooled binning, history length and time windows.

Neurohr et al. 2023 [1], sec. V-A builds a first-order, time-homogeneous chain on binned features;
sec. V-B and VII name history length and time-inhomogeneity as open problems. Both are offered
here as extensions of the state, so every test downstream stays unchanged:

* ``history = k``: the state at step t is the vector of the last k binned states
  (``x[t-k+1], …, x[t]``); a run's first state is its first full history (step k-1).
* ``time_bins = n``: the time since the run's start, binned like a feature (equal-frequency on the
  pooled times of both sets, :func:`~simcred.compare.discretize.feature_edges`), is one more
  coordinate of the state, so every time window has its own transition law.

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of ADSs,
    IEEE Access, 2023.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from simcred.compare.discretize import StateSpace, feature_edges
from simcred.errors import OptionError
from simcred.limits import check_count

WINDOW = "window"
#: Rows whose bin indices are held at a time while a first-order chain's codes are computed.
CODE_CHUNK = 2**20


@dataclass(frozen=True, slots=True, eq=False)
class EncodedRuns:
    """State codes of the runs of one set: ``codes[offsets[i]:offsets[i + 1]]`` is run ``i``."""

    codes: np.ndarray
    offsets: np.ndarray


def elapsed(time: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Time since the start of each row's run."""
    return time - np.repeat(time[offsets[:-1]], np.diff(offsets))


def state_space(values: Sequence[np.ndarray], times: Sequence[np.ndarray],
                offsets: Sequence[np.ndarray], bins: Sequence[int], features: Sequence[str],
                history: int = 1, time_bins: int | None = None) -> StateSpace:
    """The grid of (lagged) binned features, plus the time window when ``time_bins`` is set.

    Edges come from the pooled values of all sets; with history, every lag uses the same edges.
    """
    space = StateSpace.pooled(values, bins, features).lagged(history)
    if time_bins is None:
        return space
    pooled = np.concatenate([elapsed(t, o) for t, o in zip(times, offsets, strict=True)])
    return space.with_extra(WINDOW, feature_edges(pooled, time_bins),
                            (float(pooled.min()), float(pooled.max())))


def encode(space: StateSpace, values: np.ndarray, time: np.ndarray, offsets: np.ndarray,
           history: int = 1, windowed: bool = False, source: str = "<memory>") -> EncodedRuns:
    """State codes of one set on ``space`` (built by :func:`state_space` with the same options).

    The layout: ``history`` lagged copies of the base features, then the time window if
    ``windowed``.
    """
    lengths = np.diff(offsets)
    short = np.flatnonzero(lengths < history)
    if short.size:
        raise OptionError(f"{source}: run {int(short[0]) + 1} has {lengths[short[0]]} steps; "
                          f"history {history} needs at least {history}")
    if history == 1 and not windowed:
        return EncodedRuns(_chunked_codes(space, values), offsets.astype(np.int64))
    n_base = values.shape[1]
    base = [np.searchsorted(space.edges[j], values[:, j], side="right").astype(np.int32)
            for j in range(n_base)]
    keep = slice(None)
    if history > 1:
        position = np.arange(len(values)) - np.repeat(offsets[:-1], lengths)
        keep = np.flatnonzero(position >= history - 1)
    columns = [column[keep] if lag == 0 else column[keep - lag]
               for lag in range(history - 1, -1, -1) for column in base]
    if windowed:
        columns.append(np.searchsorted(space.edges[-1], elapsed(time, offsets)[keep],
                                       side="right").astype(np.int32))
    codes = np.ravel_multi_index(tuple(columns), space.shape).astype(
        code_dtype(space.n_states), copy=False)
    new_offsets = offsets - np.arange(len(offsets)) * (history - 1)
    return EncodedRuns(codes, new_offsets.astype(np.int64))


def code_dtype(n_states: int) -> type:
    """int32 where every code ``0 .. n_states - 1`` fits (4 bytes a row instead of 8), else
    int64."""
    return np.int32 if n_states <= 2**31 else np.int64


def _chunked_codes(space: StateSpace, values: np.ndarray) -> np.ndarray:
    """The codes of the first-order chain on ``space`` (:func:`encode` with history 1 and no
    time window), :data:`CODE_CHUNK` rows at a time: no full-length bin index column is made."""
    codes = np.empty(len(values), dtype=code_dtype(space.n_states))
    for lo in range(0, len(values), CODE_CHUNK):
        chunk = values[lo:lo + CODE_CHUNK]
        codes[lo:lo + len(chunk)] = np.ravel_multi_index(
            tuple(np.searchsorted(e, chunk[:, j], side="right")
                  for j, e in enumerate(space.edges)), space.shape)
    return codes


def check_history(history: int) -> int:
    if isinstance(history, bool) or not isinstance(history, int | np.integer) or history < 1:
        raise OptionError(f"history must be an integer >= 1 (1 = the paper's first-order "
                          f"chain), got {history!r}")
    return check_count(int(history), "steps", "history")  # K steps of one run per state


def check_time_bins(time_bins: int | None) -> int | None:
    if time_bins is None:
        return None
    if isinstance(time_bins, bool) or not isinstance(time_bins, int | np.integer) \
            or time_bins < 2:
        raise OptionError(f"time-bins must be an integer >= 2 (omit it for the paper's "
                          f"time-homogeneous chain), got {time_bins!r}")
    return int(time_bins)
