"""The variation campaign of [1] §V (``simcred vary``): vary, resimulate, assess, judge validity.

1. :func:`~simcred.scenario.variation.generate_variations` makes ``n`` locally varied TO
   trajectories around the lane change (C2 Bézier, refitted, plausibility-checked).
2. The kept ones are resimulated in batches (in-process or on Dask), with the same AD function,
   vehicle model and sensor model as the reprocessing; so is the unvaried description, the
   reference ("rGT" when the description is fit(GT)).
3. Each resimulated run is assessed on its trace — the simulator's output is smooth and
   consistent, so it needs no refit: the maximum TTR risk (every ``risk_dt``), the EGO's reaction
   and manoeuvre, and whether the TO still cuts in (its centre enters the EGO's lane).
4. Validity (beyond [1], which leaves it open): the varied TO trajectories are compared with the
   original's by paper 000's comparison (Markov chains over the TO's (x, y), permutation test),
   and every variation whose TO path leaves a corridor of ``max_deviation`` around the original,
   or that changes the scenario's category, is flagged.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from simcred._json import JsonResult, dumps, envelope
from simcred.compare import compare
from simcred.compare.result import Comparison
from simcred.engine import Engine, shared
from simcred.errors import SimcredError
from simcred.kinematics import LANE_WIDTH, MOTION_SIGNALS, Track
from simcred.reprocess.reaction import Reaction, ReactionCriteria, reaction
from simcred.risk import PredictionSet, VehicleStates, max_risk
from simcred.risk.scene import STATE_FIELDS
from simcred.scenario.description import ScenarioDescription
from simcred.scenario.variation import (
    PlausibilityLimits,
    VariationOptions,
    VariationSet,
    generate_variations,
)
from simcred.sim.driver import DriverConfig
from simcred.sim.resimulation import resimulate
from simcred.sim.sensors import Sensor
from simcred.traces import TIME, TraceSet, concat, handed_over, spans

REFERENCE = "original"
CAMPAIGN_NODES = 5
#: ``VaryConfig.chunk_size`` on Dask or a checkpointed engine when it is None
AUTO_CHUNK_SIZE = 50


@dataclass(frozen=True, slots=True)
class VaryConfig:
    """Options of the campaign (defaults: [1] Fig. 8's 300 variations)."""

    n: int = 300
    seed: int = 0  # as every paper-002 command; paper 002 passes its seed + 1
    vehicle: str = "ks"
    dt: float = 0.01
    risk_dt: float = 0.1
    ego: str = "ego"
    to: str = "to"
    # variations per task (generation and resimulation); None: all in one task in-process
    # (a batch of n resimulates in one closed loop, 2.2x faster than chunks of 50; results do
    # not depend on the chunks), AUTO_CHUNK_SIZE on Dask or checkpointed
    chunk_size: int | None = None
    max_deviation: float = 1.0  # m: corridor around the original TO path (≈ 3 σ of the offsets)
    lane_width: float = LANE_WIDTH
    compare_bins: int = 8
    options: VariationOptions = field(default_factory=lambda: VariationOptions(sample_dt=0.1))
    limits: PlausibilityLimits = field(default_factory=PlausibilityLimits)
    driver: DriverConfig = field(default_factory=DriverConfig)
    criteria: ReactionCriteria = field(default_factory=ReactionCriteria)
    # the TO predictions of the risk: "keep" as 5 quadrature nodes instead of the default 11
    # (1.6x faster; each variation's maximum risk within 0.03 decades of 11 nodes' on the
    # cut-in, docs/variation.md; tested)
    predictions: PredictionSet = field(
        default_factory=lambda: PredictionSet(acceleration_nodes=CAMPAIGN_NODES))


@dataclass(frozen=True, slots=True)
class Outcome(JsonResult):
    """How one resimulated run went."""

    index: int
    max_risk: float
    reaction: Reaction
    cuts_in: bool
    max_deviation: float

    def same_category(self, reference: Outcome) -> bool:
        """The original's scenario category: the TO cuts in (or not) and the EGO reacts (or
        not) as in the reference."""
        return (self.cuts_in == reference.cuts_in
                and (self.reaction.manoeuvre == "none") == (reference.reaction.manoeuvre == "none"))

    def valid(self, config: VaryConfig, reference: Outcome) -> bool:
        """Inside the corridor around the original TO path and in the original's category."""
        return self.max_deviation <= config.max_deviation and self.same_category(reference)

    def to_dict(self) -> dict[str, Any]:  # deliberate: the reaction flattened to reaction_*
        return {"index": self.index, "max_risk": self.max_risk, "cuts_in": self.cuts_in,
                "max_deviation": self.max_deviation, **{
                    f"reaction_{k}": v for k, v in self.reaction.to_dict().items()}}


@dataclass(frozen=True, slots=True, eq=False)
class VariationCampaign(JsonResult):
    """Everything :func:`run_campaign` produced; :meth:`to_dict` is :meth:`summary`."""

    config: VaryConfig
    variations: VariationSet
    reference: Outcome
    outcomes: tuple[Outcome, ...]
    runs: TraceSet
    reference_runs: TraceSet
    comparison: Comparison

    @property
    def max_risks(self) -> np.ndarray:
        return np.array([o.max_risk for o in self.outcomes])

    def __repr__(self) -> str:
        v = self.variations
        return (f"VariationCampaign({v.generated} generated, {v.kept} kept, reference max risk "
                f"{self.reference.max_risk:.3g})")

    def to_dict(self) -> dict[str, Any]:
        return self.summary()

    def summary(self) -> dict[str, Any]:  # deliberate: derived statistics, nested groups
        c, v = self.config, self.variations
        risks = self.max_risks
        valid = [o.valid(c, self.reference) for o in self.outcomes]
        manoeuvres = [o.reaction.manoeuvre for o in self.outcomes]
        return {
            "generated": v.generated, "kept": v.kept, "rejected": v.rejected,
            "rejections": v.rejections, "seed": v.seed,
            "reference": self.reference.to_dict(),
            "max_risk_percentiles": dict(zip(("p5", "p25", "p50", "p75", "p95"),
                                             np.percentile(risks, [5, 25, 50, 75, 95]).tolist(),
                                             strict=True)),
            "reference_risk_percentile": float(np.mean(risks < self.reference.max_risk) * 100),
            "manoeuvres": {m: manoeuvres.count(m) for m in sorted(set(manoeuvres))},
            "same_category": float(np.mean([o.same_category(self.reference)
                                            for o in self.outcomes])),
            "validity": {"max_deviation": c.max_deviation,
                         "outside": [o.index for o, ok in zip(self.outcomes, valid, strict=True)
                                     if not ok],
                         "to_distance_vs_original": self.comparison.distance,
                         "start_differs": self.comparison.start.rejected},
            "variations": [o.to_dict() for o in self.outcomes],
        }


def run_campaign(description: ScenarioDescription, config: VaryConfig | None = None, *,
                 sensor: Sensor | None = None, runner: Engine | None = None,
                 progress_for=lambda description: None) -> VariationCampaign:
    """Generate, resimulate and assess the variations of ``description`` (see the module)."""
    c = VaryConfig() if config is None else config
    runner = runner or Engine()
    c = replace(c, chunk_size=task_size(c, runner))
    variations = generate_variations(description, c.n, c.seed, to=c.to, ego=c.ego,
                                     options=c.options, limits=c.limits, runner=runner,
                                     chunk_size=c.chunk_size,
                                     progress=progress_for("generating variations"))
    if not variations.variations:
        reasons = ", ".join(f"{k}: {v}" for k, v in variations.rejections.items())
        raise SimcredError(f"all {variations.generated} variations of object '{c.to}' were "
                           f"rejected ({reasons}); nothing to resimulate (the original itself: "
                           f"{', '.join(variations.original_reasons) or 'plausible'})")
    parts = runner.map(_resimulate_chunk, [(-1, [description])] + jobs(variations, c),
                       shared_values={"config": c, "sensor": sensor, "original": description,
                                      "indices": [v.index for v in variations.variations]},
                       progress=progress_for("resimulating variations"))
    reference_runs, reference = parts[0]
    outcomes = tuple(o for _, chunk in parts[1:] for o in chunk)
    runs = concat([p[0] for p in parts[1:]]) if len(parts) > 1 else reference_runs
    comparison = _compare_to_original(runs, reference_runs, c)
    return VariationCampaign(c, variations, reference[0], outcomes, runs, reference_runs,
                             comparison)


def task_size(c: VaryConfig, runner: Engine) -> int:
    """``c.chunk_size``, or where it is None: ``c.n`` in-process (one task, one batch),
    :data:`AUTO_CHUNK_SIZE` on any other engine (Dask, checkpointed)."""
    if c.chunk_size is not None:
        return c.chunk_size
    return max(1, c.n) if type(runner) is Engine else AUTO_CHUNK_SIZE


def jobs(variations: VariationSet, c: VaryConfig) -> list[tuple[int, list[ScenarioDescription]]]:
    """The resimulation tasks of the kept variations: (first position, descriptions) of each
    chunk of ``c.chunk_size`` (an int here)."""
    kept = variations.variations
    return [(k, [v.description for v in kept[k:k + c.chunk_size]])
            for k in range(0, len(kept), c.chunk_size)]


def _resimulate_chunk(job: tuple[int, list[ScenarioDescription]]
                      ) -> tuple[TraceSet, list[Outcome]]:
    start, descriptions = job
    c: VaryConfig = shared("config")
    original: ScenarioDescription = shared("original")
    indices = [-1] if start < 0 else shared("indices")[start:start + len(descriptions)]
    runs = resimulate(descriptions, sensor=shared("sensor"), vehicle=c.vehicle,
                      driver=c.driver, dt=c.dt, seed=c.seed, ego=c.ego,
                      indices=[max(i, 0) for i in indices])
    if start < 0:
        runs = replace(runs, run_ids=(REFERENCE,))
    path = original.objects[c.to].positions(runs.run(0)[TIME])
    tracks = [tuple(Track.from_columns(runs.run(k), name, time=TIME).with_rates()
                    for name in (c.ego, c.to)) for k in range(len(indices))]
    peaks = _max_risks(tracks, c)
    return runs, [_assess(ego, to, i, peak, path, c)
                  for (ego, to), i, peak in zip(tracks, indices, peaks, strict=True)]


def _max_risks(tracks: list[tuple[Track, Track]], c: VaryConfig) -> np.ndarray:
    """Each run's maximum TTR risk (every ``risk_dt``, with ``c.predictions``), all runs in one
    :func:`max_risk` call (the same values as ``risk(..., predictions=c.predictions).risk.max()``
    run by run)."""
    states = []
    for ego, to in tracks:
        step = max(1, int(round(c.risk_dt / (ego.t[1] - ego.t[0]))))
        states.append((VehicleStates.of_tracks(ego[::step], name=c.ego),
                       VehicleStates.of_tracks([to[::step]], name="objects")))
    ego, objects = ({f: np.concatenate([getattr(s[j], f) for s in states]) for f in STATE_FIELDS}
                    for j in (0, 1))
    return max_risk(VehicleStates(**ego, name=c.ego), VehicleStates(**objects, name="objects"),
                    predictions=c.predictions, sizes=[s[0].shape[0] for s in states])


def _assess(ego: Track, to: Track, index: int, peak: float,
            original: tuple[np.ndarray, np.ndarray], c: VaryConfig) -> Outcome:
    ego_reaction = reaction(ego.t, ego.y, ego.v, ego.heading, ego.acceleration, c.criteria)
    lateral = np.abs(to.y - ego.y[0])
    deviation = np.hypot(to.x - original[0], to.y - original[1])
    return Outcome(index, float(peak), ego_reaction,
                   bool((lateral < c.lane_width / 2).any() and lateral[0] >= c.lane_width / 2),
                   float(deviation.max()))


def _compare_to_original(runs: TraceSet, reference: TraceSet, c: VaryConfig) -> Comparison:
    """Paper 000's distance between the varied TO trajectories and as many copies of the original's
    (the original is one deterministic trajectory)."""
    features = [f"{c.to}.{s}" for s in MOTION_SIGNALS[:2]]
    step = max(1, int(round(c.risk_dt / c.dt)))
    varied = _subsample(runs, features, step)
    one = _subsample(reference, features, step)
    rows, offsets = spans(np.zeros(runs.n_runs), np.full(runs.n_runs, one.n_rows))
    copies = TraceSet(one.signals, handed_over(one.time[rows]), handed_over(one.values[rows]),
                      offsets, tuple(f"original_{i}" for i in range(runs.n_runs)), {}, "original")
    return compare(varied, copies, features=features, bins=c.compare_bins,
                   test="permutation", seed=c.seed)


def _subsample(traces: TraceSet, features: list[str], step: int) -> TraceSet:
    runs = []
    for i in range(traces.n_runs):
        run = traces.run(i)
        runs.append({TIME: run[TIME][::step], **{f: run[f][::step] for f in features}})
    return TraceSet.from_runs(runs, run_ids=traces.run_ids, source=traces.source)


def risk_percentile_claim_values(campaign: VariationCampaign) -> tuple[float, float, float]:
    """(p5, reference max risk, p95) of the variations' maximum risks."""
    p5, p95 = np.percentile(campaign.max_risks, [5, 95])
    return float(p5), campaign.reference.max_risk, float(p95)


def summary_text(campaign: VariationCampaign) -> str:
    """``variations.json``'s text (what ``simcred vary --json`` prints)."""
    base = "sha256:" + hashlib.sha256(campaign.variations.base.to_json().encode()).hexdigest()
    return dumps(envelope("variation_campaign", campaign.summary(), inputs={"description": base}))


def write_campaign(campaign: VariationCampaign, directory) -> dict[str, Any]:
    """``variations.json`` (summary), ``variation_set.json`` (every variation: records and kept
    TO tracks), ``runs.parquet`` (resimulated runs), ``reference.parquet`` and
    ``comparison.json``; :func:`simcred.report.reprocessing.write_variations` adds Fig. 8."""
    from pathlib import Path

    from simcred.io import parquet

    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    files = {"summary": out / "variations.json", "variations": out / "variation_set.json",
             "runs": out / "runs.parquet", "reference": out / "reference.parquet",
             "comparison": out / "comparison.json"}
    files["summary"].write_text(summary_text(campaign))
    campaign.variations.write(files["variations"])
    parquet.write(campaign.runs, files["runs"])
    parquet.write(campaign.reference_runs, files["reference"])
    files["comparison"].write_text(campaign.comparison.to_json())
    return files
