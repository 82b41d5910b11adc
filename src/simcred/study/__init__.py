"""Studies on real data: whole validity questions answered end to end (data → simulation →
per-region comparison → findings), on the per-region engine of ``validate``
(:mod:`simcred.regions`). Sits above compare, regions and sim, below report and cli."""

from simcred.study.car_following import (
    StudyOptions,
    StudyResult,
    repeat_baselines,
    run_study,
)
from simcred.study.files import write_study

__all__ = ["StudyOptions", "StudyResult", "repeat_baselines", "run_study", "write_study"]
