"""Reference runs for example (a): car following at 10-25 m/s — is SUMO-IDM valid for it?

REAL reference data: the human-driven following episodes of OpenACC shipped with simcred
(:func:`simcred.io.openacc.read_openacc`, default episode rules; JRC, CC BY 4.0, see
``simcred data``), written at their recorded 0.1 s step to ``human.parquet``. The candidates are
made by ``simcred validate`` itself: the validation file's simulator commands replay every human
episode in SUMO (``simcred simulate sumo-following``: the recorded leader imposed, the follower
starting from the recorded gap and speed), so simulated and real followers face the same leaders.
The comparison resamples every run to 0.5 s (as ``simcred study car-following`` thins).

Signals: ``gap`` [m], ``dv`` [m/s] (leader − follower), ``v`` [m/s] (follower), ``a`` [m/s²],
``v_leader`` [m/s]. Usage::

    python examples/validate/car_following/make_runs.py --out examples/validate/car_following
"""

from __future__ import annotations

import argparse
from pathlib import Path

from simcred.io.openacc import HUMAN, read_openacc


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", type=Path, default=Path(__file__).parent)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    read_openacc(follower=HUMAN).write(args.out / "human.parquet")


if __name__ == "__main__":
    main()
