"""The reprocessing pipeline of Wagner, Groh et al. (paper 002) Fig. 1: measurement → fit →
resimulation → refit → risk, reaction and the error of every step; and the variation campaign.

Modules: ``representation`` (typed names GT, SD, rGT, rSD, [sb], fit(…)), ``pipeline``
(:func:`reprocess`; ``RiskSeries``: risk, TTC, THW), ``errors`` (Fig. 4), ``reaction`` (eqs. 4-7:
``ReactionAnalysis``), ``inputs`` (what ``simcred reprocess`` reads), ``timebase`` (a drive's
recordings, gaps and common time base), ``obstacles`` (every CommonRoad obstacle as the TO),
``output`` (what it writes, figures aside), ``vary`` (sec. V campaign).
"""

from simcred.reprocess.decomposition import ErrorStats, decompose
from simcred.reprocess.inputs import LongColumns, read_measurement
from simcred.reprocess.obstacles import reprocess_obstacles
from simcred.reprocess.output import write
from simcred.reprocess.pipeline import ReprocessConfig, Reprocessed, RiskSeries, reprocess
from simcred.reprocess.reaction import (
    Reaction,
    ReactionAnalysis,
    ReactionCriteria,
    ReactionTiming,
    reaction,
)
from simcred.reprocess.representation import GT, SD, Rep, SensorKind, Source
from simcred.reprocess.timebase import Drive, Gap, RecordedTracks, Recording, align
from simcred.reprocess.vary import (
    Outcome,
    VariationCampaign,
    VaryConfig,
    run_campaign,
    write_campaign,
)

__all__ = [
    "GT",
    "SD",
    "VariationCampaign",
    "Drive",
    "ErrorStats",
    "Gap",
    "LongColumns",
    "Outcome",
    "Reaction",
    "ReactionAnalysis",
    "ReactionTiming",
    "RecordedTracks",
    "Recording",
    "ReactionCriteria",
    "Rep",
    "ReprocessConfig",
    "Reprocessed",
    "RiskSeries",
    "SensorKind",
    "Source",
    "VaryConfig",
    "align",
    "decompose",
    "read_measurement",
    "reaction",
    "reprocess",
    "reprocess_obstacles",
    "run_campaign",
    "write",
    "write_campaign",
]
