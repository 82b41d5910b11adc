"""Runs for example (b): is the KS resimulation valid for the cut-in test case of paper 002?

Manufactured data (simcred's cut-in universe, paper 002), not recordings:

* reference ``reality.parquet``: the cut-in driven by the AD function in "reality" (single-track
  model ST, the tracker sensor), measured by the DGPS noise of the ground truth (GT) —
  ``runs`` variations of the TO's script (start distance, speed, braking) drawn from ``seed``;
* candidate ``ks.parquet``: the resimulation of the same scripts with the kinematic single-track
  model KS (the TO follows its ground-truth trajectory exactly: a perfect scenario description),
  with independent sensor noise.

Signals at 10 Hz: ``ego.v``, ``ego.a`` (acceleration command), ``ego.y``, ``ego.heading``,
``range`` (TO centre ahead of the EGO's centre) and ``to.brake``, the TO's scripted braking
deceleration (m/s², constant per run: the exogenous operating condition). Each run's per-run
facts name its ``script`` (the index of the TO's drawn script), which pairs a resimulation with
the reference run it replays. Usage::

    python examples/validate/cutin/make_runs.py --out examples/validate/cutin --runs 120
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np

from simcred.seeds import stream as run_rng
from simcred.sim.closed_loop import run_closed_loop
from simcred.sim.driver import ADFunction
from simcred.sim.experiments.cutin import (
    CutInConfig,
    DGPSNoise,
    scripted_object,
    vehicle_model,
)
from simcred.traces import RUN_INFO, TraceSet

THIN = 10  # 100 Hz simulation, 10 Hz runs


def scripts(runs: int, seed: int, base: CutInConfig):
    rng = np.random.default_rng(seed)
    for _ in range(runs):
        yield replace(base.script, start_distance=rng.uniform(20.0, 45.0),
                      speed=rng.uniform(18.0, 28.0), brake_decel=rng.uniform(2.0, 8.0),
                      brake_start=rng.uniform(3.0, 5.0))


def drive(model: str, runs: int, seed: int, noise_seed: int, name: str) -> TraceSet:
    config = CutInConfig()
    t = np.arange(config.steps) * config.dt
    drawn = list(scripts(runs, seed, config))
    truth = np.stack([scripted_object(s, t) for s in drawn])[:, :, None, :]
    noise = np.stack([run_rng(noise_seed, i).standard_normal((config.steps, 1, 2))
                      for i in range(runs)])
    ego_start = np.tile([0.0, 0.0, config.ego_speed, 0.0], (runs, 1))
    record = run_closed_loop(vehicle_model(model), ego_start, truth, config.sensor,
                             ADFunction(config.driver), config.dt, noise)
    dgps = DGPSNoise()
    rng = np.random.default_rng(noise_seed + 1)
    ego, to = record.ego, record.objects
    speed = ego.v[:, ::THIN]
    v = speed + dgps.speed * rng.standard_normal(speed.shape)
    brake = np.repeat([[s.brake_decel] for s in drawn], speed.shape[1], axis=1)
    columns = {"ego.v": v, "ego.a": ego.acceleration[:, ::THIN], "ego.y": ego.y[:, ::THIN],
               "ego.heading": ego.heading[:, ::THIN],
               "range": to.x[:, ::THIN, 0] - ego.x[:, ::THIN], "to.brake": brake}
    return TraceSet.from_runs([{"t": record.t[::THIN], **{k: c[i] for k, c in columns.items()}}
                               for i in range(runs)],
                              run_ids=[f"{name}{i:03d}" for i in range(runs)],
                              metadata={"example": "validate cut-in", "model": model,
                                        "seed": seed, "noise_seed": noise_seed,
                                        "manufactured": True,
                                        RUN_INFO: {f"{name}{i:03d}": {"script": i}
                                                   for i in range(runs)}}, source=name)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=Path(__file__).parent)
    parser.add_argument("--runs", type=int, default=120)
    parser.add_argument("--seed", type=int, default=2)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    drive("st", args.runs, args.seed, 100, "reality").write(args.out / "reality.parquet")
    drive("ks", args.runs, args.seed, 200, "ks").write(args.out / "ks.parquet")
    # a second ST set with other noise: the same-model twin, valid by construction
    drive("st", args.runs, args.seed, 300, "st").write(args.out / "st.parquet")


if __name__ == "__main__":
    main()
