"""Every obstacle of a CommonRoad scenario as the traffic object, one reprocessing each
(``simcred reprocess SCENARIO.xml --object all``).

Each obstacle with a trajectory is reprocessed with its follower as the EGO
(:func:`simcred.reprocess.inputs.commonroad_drive`). An obstacle that cannot be reprocessed
(no follower, too few shared time steps, a fit or an assessment that fails) is reported with
the reason and the stage where it failed; the others go on. The summary lists every obstacle.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simcred._json import JsonResult
from simcred.errors import SimcredError
from simcred.reprocess.inputs import commonroad_drive, commonroad_obstacles
from simcred.reprocess.pipeline import Progress, ReprocessConfig, Reprocessed, reprocess

Writer = Callable[[Reprocessed, Path], Any]


@dataclass(frozen=True, slots=True)
class ObstacleOutcome(JsonResult):
    """How reprocessing one obstacle went: ``status`` "ok" or "failed" (with stage and
    reason)."""

    obstacle: int
    status: str
    stage: str = ""
    reason: str = ""
    summary: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"obstacle": self.obstacle, "status": self.status}
        if self.status != "ok":
            out.update(stage=self.stage, reason=self.reason)
        return out | self.summary


@dataclass(frozen=True, slots=True)
class ObstacleBatch(JsonResult):
    """All obstacles' outcomes; :meth:`to_dict` is ``reprocess_all.json``'s body."""

    source: str
    outcomes: tuple[ObstacleOutcome, ...]

    @property
    def failed(self) -> tuple[ObstacleOutcome, ...]:
        return tuple(o for o in self.outcomes if o.status != "ok")

    def to_dict(self) -> dict[str, Any]:
        return {"source": self.source, "obstacles": len(self.outcomes),
                "reprocessed": len(self.outcomes) - len(self.failed),
                "failed": len(self.failed), "outcomes": [o.to_dict() for o in self.outcomes]}


def reprocess_obstacles(path: str | Path, config: ReprocessConfig, out: str | Path,
                        write: Writer, progress: Progress | None = None, *,
                        frame: str = "ego") -> ObstacleBatch:
    """Reprocess every obstacle of ``path`` as the TO; write each into ``out/obj<id>/``
    (``frame``: the road frame of :func:`~simcred.reprocess.inputs.commonroad_drive`)."""
    say = progress or (lambda _: None)
    traces, ids = commonroad_obstacles(path)
    outcomes = []
    for obstacle in ids:
        say(f"obstacle {obstacle}")
        outcomes.append(_one(path, traces, obstacle, config, Path(out) / f"obj{obstacle}",
                             write, frame))
    return ObstacleBatch(str(path), tuple(outcomes))


def _one(path, traces, obstacle: int, config: ReprocessConfig, out: Path,
         write: Writer, frame: str) -> ObstacleOutcome:
    stage = "input"
    try:
        drive = commonroad_drive(path, obstacle, traces=traces, frame=frame)
        stage = "pipeline"
        result = reprocess(drive, config)
        stage = "output"
        write(result, out)
    except SimcredError as exc:
        return ObstacleOutcome(obstacle, "failed", stage, _line(exc))
    except Exception as exc:  # a failing step must not abort the other obstacles
        return ObstacleOutcome(obstacle, "failed", stage,
                               f"internal error {type(exc).__name__}: {_line(exc)}")
    return ObstacleOutcome(obstacle, "ok", summary=_summary(result, out))


def _line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _summary(result: Reprocessed, out: Path) -> dict[str, Any]:
    drive = result.drive_metadata
    return {"ego": drive.get("ego"), "ego_choice": drive.get("ego_choice"),
            "directory": out.name, "samples": len(result.times),
            "gaps": 0 if result.aligned is None else len(result.aligned.gaps),
            "reactions": {k: r.manoeuvre for k, r in result.reactions.items()},
            "reactions_not_measurable": [k for k, r in result.reactions.items()
                                         if not r.measurable],
            "max_risk": {k: r.max_risk for k, r in result.risk.items()}}
