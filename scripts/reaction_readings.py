"""Paper 002's eqs. (4)-(7) on both readings of the reaction, as the manufactured universe varies
(issue 24 point 7). Sensitivities, not choices: the shipped universe is unchanged.

For each setting the default cut-in drive (seed 0, ``cutin.simulate``) is reprocessed with the
same AD function and the ideal sensor only (``ReprocessConfig(scenario_based=False)``), and the
claims of :func:`simcred.paper.reprocessing.reaction_claims` are judged by their bounds in the
code. Per setting: the manoeuvres of GT, rGT, rSD, Δt_react(GT, rGT) (eq. 4) and its ratio to
t_ΔS,d (eq. 6) on the onset of the speed drop ([1]'s reading) and on the emergency braking.

``--study window``: the real sensor's regression window (``TrackerSensor.window``, default
1 s: a velocity delay of ≈ window / 2), and a sensor with the offset only (no delay, no noise).
``--study cut-in``: the AD function's cut-in trigger (``DriverConfig.cut_in``, ``cut_in_tlc``,
``cut_in_lateral_speed``), with the default sensor.

    PYTHONPATH=src OPENBLAS_NUM_THREADS=1 python scripts/reaction_readings.py --study window
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np

from simcred import __version__
from simcred.paper.reprocessing import reaction_claims, reading_values
from simcred.reprocess.pipeline import ReprocessConfig, reprocess
from simcred.sim.experiments import cutin
from simcred.sim.sensors import OffsetDelaySensor

ROOT = Path(__file__).resolve().parents[1]
UNIVERSE = cutin.CutInConfig()
WINDOWS = (0.5, 1.0, 2.0)  # s
TLCS = (0.5, 1.0, 1.5, 2.0)  # s
LATERAL_SPEEDS = (0.1, 0.3, 0.5)  # m/s
CLAIMS = ("reaction_shift_eq4", "reaction_shift_eq6", "reaction_rgt_rsd_offset",
          "manoeuvre_change_fig6")


def settings(study: str) -> list[tuple[dict, cutin.CutInConfig]]:
    """(what was set, the universe) per setting of ``study``."""
    if study == "window":
        no_delay = OffsetDelaySensor(offset=UNIVERSE.sensor.offset)
        return [({"window": w}, replace(UNIVERSE, sensor=replace(UNIVERSE.sensor, window=w)))
                for w in WINDOWS] + [({"window": None, "sensor": "offset only"},
                                      replace(UNIVERSE, sensor=no_delay))]
    driver = UNIVERSE.driver
    out = [({"cut_in": False}, replace(UNIVERSE, driver=replace(driver, cut_in=False)))]
    for tlc in TLCS:
        for speed in LATERAL_SPEEDS:
            out.append(({"cut_in": True, "cut_in_tlc": tlc, "cut_in_lateral_speed": speed},
                        replace(UNIVERSE, driver=replace(driver, cut_in_tlc=tlc,
                                                         cut_in_lateral_speed=speed))))
    return out


def measure(universe: cutin.CutInConfig, seed: int) -> dict:
    """One setting: manoeuvres, both readings' eqs. (4), (6), (7), the claims' verdicts."""
    result = reprocess(cutin.simulate(seed, universe),
                       ReprocessConfig(seed=seed, driver=universe.driver, scenario_based=False))
    claims = {c.id: c.passed for c in reaction_claims(result)}
    reps = ("GT", "rGT", "rSD")
    return {
        "manoeuvres": {k: result.reactions[k].manoeuvre for k in reps},
        # the TO's centre when each EGO reacts: over 1.75 m it is in the left lane, which the
        # AD function then finds occupied and brakes instead of evading
        "to_y_at_reaction": {k: _to_y(result, k) for k in reps},
        "readings": reading_values(result),
        "holds": {f"{c}{s}": claims[f"{c}{s}"] for c in CLAIMS for s in ("", "_braking")
                  if f"{c}{s}" in claims},
    }


def _to_y(result, rep: str) -> float | None:
    t, track = result.reactions[rep].time, result.states[rep]["to"]
    return None if math.isnan(t) else float(np.interp(t, track.t, track.y))


def _s(value: float | None, digits: int = 2) -> str:
    return "–" if value is None else f"{value:.{digits}f}"


def _reading(values: dict) -> str:
    """``t_GT − t_rGT = Δt (ratio)``; n/m: a time within the start margin (not measurable)."""
    t, dt = values["times"], values["dt_react_GT_rGT"]
    said = "n/m" if dt is None else f"{dt:.2f} s ({values['ratio_eq6']:.1f})"
    return f"{_s(t['GT'])} − {_s(t['rGT'])} = {said}"


def _label(setting: dict) -> str:
    if "sensor" in setting:
        return "no delay: offset 1.4 m only, no noise"
    if "window" in setting:
        return f"window {setting['window']:g} s"
    if not setting["cut_in"]:
        return "no cut-in trigger"
    return f"TLC ≤ {setting['cut_in_tlc']:g} s, ≥ {setting['cut_in_lateral_speed']:g} m/s"


def row(setting: dict, m: dict) -> str:
    r, h, y = m["readings"], m["holds"], m["to_y_at_reaction"]
    eq4 = "/".join("yes" if h[f"reaction_shift_eq4{s}"] else "no" for s in ("", "_braking"))
    return "| " + " | ".join([
        _label(setting),
        " / ".join(m["manoeuvres"].values()), f"{_s(y['rGT'])} / {_s(y['rSD'])} m",
        _reading(r["onset"]), _reading(r["braking"]),
        eq4, "yes" if h["manoeuvre_change_fig6"] else "no"]) + " |"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--study", choices=("window", "cut-in"), required=True)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    name = f"reaction_{args.study.replace('-', '_')}.json"
    out = args.out or ROOT / "benchmarks" / "results" / name
    rows = []
    print("| setting | GT / rGT / rSD | TO's y at rGT / rSD reaction | onset GT − rGT (eq. 6) "
          "| braking GT − rGT (eq. 6) | eq. 4 holds (onset/braking) | Fig. 6 holds |")
    for setting, universe in settings(args.study):
        m = measure(universe, args.seed)
        rows.append({"setting": setting, **m})
        print(row(setting, m), flush=True)
    out.write_text(json.dumps({"study": args.study, "seed": args.seed,
                               "simcred_version": __version__, "rows": rows}, indent=1) + "\n")
    print(f"wrote {out.relative_to(ROOT) if out.is_relative_to(ROOT) else out}")


if __name__ == "__main__":
    main()
