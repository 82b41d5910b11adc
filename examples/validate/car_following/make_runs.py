"""Runs for example (a): car following at 10-25 m/s — is SUMO-IDM valid for it?

REAL reference data: the human-driven following episodes of OpenACC shipped with simcred
(:func:`simcred.io.openacc.read_openacc`, default episode rules; JRC, CC BY 4.0, see
``simcred data``). Candidates: every human episode replayed in SUMO with IDM and with Krauss
(:func:`simcred.sim.sumo.replay`: the recorded leader imposed, the follower starting from the
recorded gap and speed), so the simulated and the real followers face the same leaders.
Episodes are thinned to one sample every 0.5 s (as ``simcred study car-following`` does).

Signals: ``gap`` [m], ``dv`` [m/s] (leader − follower), ``v`` [m/s] (follower), ``a`` [m/s²],
``v_leader`` [m/s]. Usage::

    python examples/validate/car_following/make_runs.py --out examples/validate/car_following
"""

from __future__ import annotations

import argparse
from pathlib import Path

from simcred.io.openacc import HUMAN, read_openacc
from simcred.sim.sumo import replay
from simcred.study.car_following import thin

EVERY = 5  # 0.1 s recordings → 0.5 s


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=Path(__file__).parent)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    human = read_openacc(follower=HUMAN)
    sims = replay(human, ["IDM", "Krauss"], seed=args.seed)
    thin(human, EVERY).write(args.out / "human.parquet")
    for name, runs in sims.items():
        thin(runs, EVERY).write(args.out / f"{name.lower()}.parquet")


if __name__ == "__main__":
    main()
