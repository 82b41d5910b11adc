"""Seed 002 (Wagner, Groh et al. 2019) §§II-IV on the manufactured cut-in universe: the
reprocessing pipeline, its error decomposition and the scenario-based sensor model, with the
paper's findings checked as claims.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from simcred.engine import Engine
from simcred.paper.claims import Claim, at_least, below, write_claims
from simcred.report.seed002 import write_reprocessed, write_variations
from simcred.reprocess.errors import ErrorStats
from simcred.reprocess.pipeline import ReprocessConfig, Reprocessed, log_risk_rmse, reprocess
from simcred.reprocess.representation import GT, Sensor
from simcred.reprocess.vary import (
    Campaign,
    VaryConfig,
    risk_percentile_claim_values,
    run_campaign,
)
from simcred.sim.experiments import cutin


def _rms(stats: ErrorStats) -> float:
    return math.hypot(stats.mean, stats.std)


def _rmse(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean((a - b) ** 2)))


def reprocess_claims(result: Reprocessed, configured_offset: float) -> list[Claim]:
    """[1]'s findings of §§III-IV, checked on ``result`` (a measurement with GT and SD)."""
    to, table = result.config.objects[0], result.errors["ideal"]
    r, a = result.reactions, result.analysis
    offset = table["S"][to]["d"].median
    claims = [below("sensor_offset",
                    "TO ΔS_d ≈ the configured sensor offset (|median − offset| < 0.1 m)",
                    abs(offset - configured_offset), 0.1,
                    f"median ΔS_d = {offset:.3f} m, configured {configured_offset} m")]
    for q, unit in (("d", "m"), ("v", "m/s")):
        gt, sd = _rms(table["FIT_GT"][to][q]), _rms(table["FIT_SD"][to][q])
        claims.append(below(f"fit_gt_below_fit_sd_{q}",
                            f"ΔFIT_GT is far below ΔFIT_SD (TO Δ{q}: RMS ratio < 0.5)",
                            gt / sd, 0.5, f"RMS ΔFIT_GT = {gt:.4f} {unit}, "
                                          f"RMS ΔFIT_SD = {sd:.4f} {unit}"))
    gt_v = result.states["GT"][to].v
    fitted, raw = (_rmse(result.states[k][to].v, gt_v) for k in ("fit(SD)", "SD"))
    claims.append(below("fit_corrects_delay",
                        "the SD fit's TO speed is closer to GT than the raw SD speed (Fig. 5)",
                        fitted, raw, f"RMSE vs GT: fit(SD) {fitted:.3f} m/s, SD {raw:.3f} m/s"))
    dt_ideal = a["dt_react_GT_rGT"]
    changed = r["rGT"].manoeuvre != r["GT"].manoeuvre
    claims.append(Claim(
        "behaviour_change_ideal",
        "with the ideal sensor the resimulated EGO reacts ≥ 0.5 s earlier than in GT and/or "
        "chooses another manoeuvre", dt_ideal, 0.5,
        bool(changed or (dt_ideal is not None and dt_ideal >= 0.5)),
        f"GT: {r['GT'].manoeuvre} at {r['GT'].time:.2f} s; rGT: {r['rGT'].manoeuvre} at "
        f"{r['rGT'].time:.2f} s"))
    t_offset, dt_rsd = a["t_offset"], a["dt_react_rGT_rSD"]
    claims.append(below("reaction_rgt_rsd_offset",
                        "Δt_react(rGT, rSD) is of the order of ΔS_d / v_EGO (eq. 7: |Δt| < 3 "
                        "t_ΔS,d)", abs(dt_rsd if dt_rsd is not None else math.inf),
                        3 * t_offset, f"t_ΔS,d = {t_offset:.3f} s (eq. 5)"))
    claims += _scenario_based_claims(result)
    return claims


def _scenario_based_claims(result: Reprocessed) -> list[Claim]:
    r = result.reactions
    rgt_sb = GT.resimulation(Sensor.SCENARIO_BASED)
    if rgt_sb not in r:
        return []
    sb = r[rgt_sb]
    gap = abs(sb.time - r["GT"].time) if not math.isnan(sb.time) else math.inf
    ideal = log_risk_rmse(result.risk["GT"], result.risk["rGT"])
    scenario_based = log_risk_rmse(result.risk["GT"], result.risk[rgt_sb])
    return [
        Claim("scenario_based_same_behaviour",
              "with the scenario-based sensor model the resimulated EGO chooses GT's manoeuvre "
              "and reacts within 0.2 s of it", gap, 0.2,
              bool(sb.manoeuvre == r["GT"].manoeuvre and gap <= 0.2),
              f"GT: {r['GT'].manoeuvre} at {r['GT'].time:.2f} s; rGT[sb]: {sb.manoeuvre} at "
              f"{sb.time:.2f} s"),
        below("scenario_based_risk_closer",
              "the scenario-based resimulation's risk curve is closer to GT's than the ideal "
              "sensor's (log10-risk RMSE)", scenario_based, ideal,
              f"log10-risk RMSE vs GT: scenario-based {scenario_based:.3f}, ideal {ideal:.3f}"),
    ]


def run_reprocessing(out: Path, *, seed: int = 0, config: cutin.CutInConfig | None = None,
                     progress=None) -> tuple[Reprocessed, list[Claim]]:
    """Simulate the cut-in measurement, reprocess it into ``out``, check the claims."""
    universe = cutin.CutInConfig() if config is None else config
    measurement = cutin.simulate(seed, universe)
    measurement.write(out / "measurement")
    result = reprocess(measurement, ReprocessConfig(seed=seed), progress)
    write_reprocessed(result, out)
    return result, reprocess_claims(result, universe.sensor.offset)


def variation_claims(campaign: Campaign) -> list[Claim]:
    """[1] §V's findings on the variations of fit(GT), resimulated like rGT."""
    summary = campaign.summary()
    p5, reference, p95 = risk_percentile_claim_values(campaign)
    manoeuvres = ", ".join(f"{k} {v}" for k, v in summary["manoeuvres"].items())
    return [
        at_least("variations_same_category",
                 "the variations stay in the scenario's category: the TO still cuts in, the EGO "
                 "still reacts (fraction of kept variations)", summary["same_category"], 0.95,
                 f"{summary['kept']} of {summary['generated']} kept; manoeuvres: {manoeuvres}"),
        Claim("variations_risk_surround_rgt",
              "the variations' maximum risks surround rGT's: it lies between their 5th and 95th "
              "percentile", reference, None, bool(p5 <= reference <= p95),
              f"p5 = {p5:.3g}, rGT = {reference:.3g}, p95 = {p95:.3g} (percentile "
              f"{summary['reference_risk_percentile']:.0f})"),
    ]


def run_variations(out: Path, result: Reprocessed, *, n: int = 300, seed: int = 1,
                   runner: Engine | None = None, progress_for=lambda _: None
                   ) -> tuple[Campaign, list[Claim]]:
    """Vary fit(GT) ``n`` times, resimulate as rGT (ideal sensor, KS), write into ``out``."""
    config = VaryConfig(n=n, seed=seed, vehicle=result.config.vehicle, dt=result.config.dt,
                        driver=result.config.driver)
    campaign = run_campaign(result.descriptions["fit(GT)"], config, runner=runner,
                            progress_for=progress_for)
    write_variations(campaign, out)
    return campaign, variation_claims(campaign)


@dataclass(frozen=True, slots=True, eq=False)
class Seed002Run:
    """What ``paper 002`` produced: the claims, the reprocessing and the variation campaign."""

    claims: list[Claim]
    result: Reprocessed
    campaign: Campaign


def run_all(out: Path, *, seed: int = 0, variations: int = 300, runner: Engine | None = None,
            progress=None, progress_for=lambda _: None) -> Seed002Run:
    """``simcred paper 002``: reprocessing and variations, plus ``claims.json``."""
    out.mkdir(parents=True, exist_ok=True)
    universe = cutin.CutInConfig()
    result, claims = run_reprocessing(out, seed=seed, config=universe, progress=progress)
    campaign, more = run_variations(out / "variations", result, n=variations, seed=seed + 1,
                                    runner=runner, progress_for=progress_for)
    write_claims(claims + more, out / "claims.json",
                 {"cutin": {"experiment": "cutin", "seed": seed, **asdict(universe)},
                  "reprocess": asdict(ReprocessConfig(seed=seed)),
                  "variations": {"n": variations, "seed": campaign.variations.seed,
                                 **asdict(campaign.config)}})
    return Seed002Run(claims + more, result, campaign)

