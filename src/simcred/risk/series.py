"""Risk from named columns: the risk of every sample of a scenario, or of all rows of a trace
set, in one call (``<vehicle>.<field>`` columns into :class:`VehicleStates`, then :func:`risk`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from simcred.errors import OptionError, SimcredError
from simcred.risk.prediction import EvasionSet, PredictionSet, ReactionTime
from simcred.risk.scene import STATE_FIELDS, Lanes, VehicleStates
from simcred.risk.ttr import RiskResult, risk


def risk_series(samples: Mapping[str, ArrayLike], *, ego: str = "ego",
                objects: Sequence[str] = ("to",), predictions: PredictionSet | None = None,
                evasion: EvasionSet | None = None, lanes: Lanes | None = None,
                reaction: ReactionTime | None = None) -> RiskResult:
    """Risk of every sample of a scenario (or of all rows of a trace set) in one call.

    Parameters
    ----------
    samples : mapping of str to array_like
        1-D columns of equal length named ``<vehicle>.<field>``: ``x``, ``y``, ``v``, ``heading``
        required; ``acceleration`` (or ``a``), ``yaw_rate``, ``length``, ``width`` optional
        (defaults of :class:`VehicleStates`). Other columns (``t``, ...) are ignored.
    ego : str, default: "ego"
        Prefix of the EGO's columns.
    objects : sequence of str, default: ("to",)
        Prefixes of the TOs' columns.
    predictions, evasion, lanes, reaction
        As for :func:`risk`.

    Returns
    -------
    RiskResult
        One scene per sample: ``risk`` is the risk time series.

    Examples
    --------
    >>> t = np.arange(0.0, 2.0, 0.5)
    >>> cols = {"ego.x": 27.8 * t, "ego.y": 0 * t, "ego.v": 27.8 + 0 * t, "ego.heading": 0 * t,
    ...         "to.x": 60 + 20 * t, "to.y": 0 * t, "to.v": 20 + 0 * t, "to.heading": 0 * t}
    >>> series = risk_series(cols)
    >>> series.ttr_min.round(2), series.risk.round(4)
    (array([1.95, 1.81, 1.67, 1.53]), array([0.0023, 0.0032, 0.0048, 0.0072]))
    """
    if isinstance(objects, str) or len(objects) == 0:
        raise OptionError("objects must be a non-empty sequence of column prefixes")
    states = [_states_from_columns(samples, ego)]
    states += [_states_from_columns(samples, name) for name in objects]
    lengths = {s.x.shape[0] for s in states}
    if len(lengths) > 1:
        raise SimcredError(f"columns of {ego}, {', '.join(objects)} differ in length")
    stacked = {f: np.stack([getattr(s, f) for s in states[1:]], axis=1) for f in STATE_FIELDS}
    return risk(states[0], VehicleStates(**stacked, name="objects"), predictions=predictions,
                evasion=evasion, lanes=lanes, reaction=reaction)


def _states_from_columns(samples: Mapping[str, ArrayLike], prefix: str) -> VehicleStates:
    values: dict[str, Any] = {}
    for f in STATE_FIELDS:
        names = [f"{prefix}.{f}"] + ([f"{prefix}.a"] if f == "acceleration" else [])
        present = [n for n in names if n in samples]
        if len(present) > 1:
            raise SimcredError(f"give one of columns {' or '.join(present)}, not both")
        if present:
            try:
                column = np.asarray(samples[present[0]], dtype=float)
            except (TypeError, ValueError):
                raise SimcredError(f"column {present[0]} must be numeric") from None
            if column.ndim != 1:
                raise SimcredError(f"column {present[0]} must be 1-D, got shape {column.shape}")
            values[f] = column
        elif f in ("x", "y", "v", "heading"):
            raise SimcredError(f"missing column {prefix}.{f}")
    states = VehicleStates(**values, name=prefix)
    if states.x.ndim != 1:
        raise SimcredError(f"columns of {prefix} must be 1-D")
    return states
