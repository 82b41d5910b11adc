"""Error decomposition of the reprocessing pipeline ([1] §III, Fig. 4, eqs. (2)-(3)).

After every step of the pipeline there is a representation of the traces; comparing a step's
output with its input on the same time samples isolates that step's error. For each object:

* Δd — Euclidean distance of the positions (m, ≥ 0);
* Δv — speed difference, output minus input (m/s, signed: [1] reports biased or unbiased);
* Δθ — heading difference wrapped to (-π, π] (rad, signed).

Each error series is summarised as in Fig. 4: quartiles, whiskers at the full extent, mean and
standard deviation.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from simcred._json import JsonResult, fields_dict
from simcred.kinematics import Track

QUANTITIES = ("d", "v", "heading")

#: The steps of Fig. 4: name -> (output, input), both keys of the pipeline's representations.
STEPS: dict[str, tuple[str, str]] = {
    "S": ("SD", "GT"),
    "FIT_GT": ("fit(GT)", "GT"),
    "FIT_SD": ("fit(SD)", "SD"),
    "SIM_GT": ("rGT", "fit(GT)"),
    "SIM_SD": ("rSD", "fit(SD)"),
    "FIT_rGT": ("fit(rGT)", "rGT"),
    "FIT_rSD": ("fit(rSD)", "rSD"),
    "RP_GT": ("fit(rGT)", "GT"),
    "RP_SD": ("fit(rSD)", "GT"),
}


@dataclass(frozen=True, slots=True)
class ErrorStats(JsonResult):
    """Summary of one error series (Fig. 4's box, whiskers and diamond)."""

    q25: float
    median: float
    q75: float
    low: float
    high: float
    mean: float
    std: float
    n: int

    @classmethod
    def of(cls, values: np.ndarray) -> ErrorStats:
        values = np.asarray(values, dtype=float)
        q25, median, q75 = np.quantile(values, [0.25, 0.5, 0.75])
        return cls(float(q25), float(median), float(q75), float(values.min()),
                   float(values.max()), float(values.mean()), float(values.std()), len(values))

    def to_dict(self) -> dict[str, float]:
        return fields_dict(self)


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-π, π]."""
    return -np.remainder(-np.asarray(angle) + np.pi, 2 * np.pi) + np.pi


def state_errors(output: Track, reference: Track) -> dict[str, np.ndarray]:
    """Δd, Δv, Δθ between two tracks on the same times."""
    return {"d": np.hypot(output.x - reference.x, output.y - reference.y),
            "v": output.v - reference.v,
            "heading": wrap(output.heading - reference.heading)}


def decompose(representations: Mapping[str, Mapping[str, Track]], objects: tuple[str, ...]
              ) -> dict[str, dict[str, dict[str, ErrorStats]]]:
    """Fig. 4's table: ``step -> object -> quantity -> ErrorStats``.

    ``representations`` maps the names used in :data:`STEPS` (``"GT"``, ``"fit(SD)"``, ...) to
    ``object -> track`` on common times; steps whose inputs are missing are skipped
    (a real recording without GT has only the SD pipeline's fit).
    """
    table: dict[str, dict[str, dict[str, ErrorStats]]] = {}
    for step, (out, ref) in STEPS.items():
        if out not in representations or ref not in representations:
            continue
        table[step] = {
            name: {q: ErrorStats.of(e) for q, e in state_errors(
                representations[out][name], representations[ref][name]).items()}
            for name in objects}
    return table
