"""Calibrate SUMO's IDM to half of the OpenACC human episodes; judge it on the other half.

The candidate ``idm_calibrated`` of ``validation.yaml`` was made with this script (defaults).

* Episodes: the human following episodes of OpenACC (``human.parquet``, see ``make_runs.py``;
  609 episodes of 10 s at 0.1 s from four recording files of 2019-10-09).
* Split (declared before fitting): by recording file, :func:`simcred.sim.sumo_calibration.halves`
  on the 10 s episodes — files largest first, each into the half with fewer episodes so far.
  Calibration half: ``handling_part22`` + ``handling_part40`` (282 episodes); held out:
  ``handling_part26`` + ``handling_part35`` (327 episodes). No recording, hence no stretch of
  driving, is in both.
* Fitted: IDM's ``tau``, ``accel``, ``decel``, ``minGap`` within the default bounds of
  :data:`~simcred.sim.sumo_calibration.PARAMETERS`, from SUMO's defaults (1.0 s, 2.6 m/s²,
  4.5 m/s², 2.5 m); everything else as in ``simcred simulate sumo-following`` (IDM ignores the
  seed; seed 0 is recorded anyway).
* Objective: mean over episodes of (NRMSE(gap) + NRMSE(v)) / 2, every step of the 0.1 s replay
  (module doc of :mod:`simcred.sim.sumo_calibration`), Nelder–Mead, at most 300 replays of the
  calibration half (1.4-3 s each on one shared core).
* Held out: judged on the 10 s episodes of the held-out files and on the same files cut into
  60 s episodes (a longer horizon; same episode rules otherwise).
* ``--duration 60``: fit on the calibration files cut into 60 s episodes instead (same files).

Writes ``idm_calibrated.json`` (or ``--out``) next to this script: fitted values, bounds, the
split's files and episode counts, the objective before/after on both halves, the search's facts,
versions; no times, so a rerun writes the same bytes. Usage::

    python examples/validate/car_following/calibrate_idm.py            # ~5 min
    python examples/validate/car_following/calibrate_idm.py --duration 60 \\
        --out examples/validate/car_following/idm_calibrated_60s.json  # ~2-4 min
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

from simcred._json import dumps, envelope
from simcred._version import __version__
from simcred.io.openacc import HUMAN, EpisodeRules, read_openacc
from simcred.sim.sumo import sumo_version
from simcred.sim.sumo_calibration import DEFAULT_PARAMETERS, calibrate, evaluate, halves
from simcred.traces import RUN_INFO, TraceSet, take

HERE = Path(__file__).parent
#: The held-out half is also judged on episodes of this length [s] (a longer horizon: a follower
#: that hardly reacts can do well over 10 s and drift away over a minute).
CHECK_DURATION = 60.0


def _by_file(traces: TraceSet, files: set[str]) -> TraceSet:
    info = traces.metadata[RUN_INFO]
    return take(traces, [i for i, r in enumerate(traces.run_ids) if info[r]["file"] in files])


def _files(traces: TraceSet) -> dict[str, int]:
    info = traces.metadata[RUN_INFO]
    names = [info[r]["file"] for r in traces.run_ids]
    return {f: names.count(f) for f in sorted(set(names))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=HERE / "human.parquet",
                        help="10 s human episodes (default: human.parquet here, else read OpenACC)")
    parser.add_argument("--out", type=Path, default=HERE / "idm_calibrated.json")
    parser.add_argument("--max-evaluations", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--params", default=",".join(DEFAULT_PARAMETERS),
                        help="IDM vType attributes to fit, comma-separated (default: %(default)s)")
    parser.add_argument("--duration", type=float, default=10.0,
                        help="episode length [s] of the calibration episodes (default: 10)")
    args = parser.parse_args()

    human = TraceSet.read(args.data) if args.data.exists() else read_openacc(follower=HUMAN)
    info = human.metadata[RUN_INFO]
    first, second = halves(human, by="file")
    cal_files, held_files = ({info[r]["file"] for r in half} for half in (first, second))
    held = _by_file(human, held_files)
    long = None if args.duration == 10.0 else read_openacc(
        follower=HUMAN, rules=EpisodeRules(duration=args.duration))
    fit = _by_file(human if long is None else long, cal_files)
    print(f"calibration half {_files(fit)}; held out {_files(held)}", file=sys.stderr)

    started = time.perf_counter()

    def log(count: int, values: dict, value: float) -> None:
        shown = ", ".join(f"{k}={v:.3f}" for k, v in values.items())
        print(f"  {count:3d}  J={value:.5f}  {shown}  ({time.perf_counter() - started:.0f} s)",
              file=sys.stderr)

    params = [p.strip() for p in args.params.split(",") if p.strip()]
    result = calibrate(fit, "IDM", params, seed=args.seed,
                       max_evaluations=args.max_evaluations, log=log)
    seconds = time.perf_counter() - started
    halves_out = {
        "calibration_half": {"default": result.before, "calibrated": result.after},
        "held_out_half": {"default": evaluate(held, result.start, seed=args.seed),
                          "calibrated": evaluate(held, result.model, seed=args.seed)}}
    inputs = {"episodes": human.digest()}
    for duration in sorted({CHECK_DURATION, args.duration} - {10.0}):
        episodes = long if duration == args.duration else read_openacc(
            follower=HUMAN, rules=EpisodeRules(duration=duration))
        inputs[f"episodes_{duration:g}s"] = episodes.digest()
        held_long = _by_file(episodes, held_files)
        halves_out[f"held_out_half_{duration:g}s"] = {
            "default": evaluate(held_long, result.start, seed=args.seed),
            "calibrated": evaluate(held_long, result.model, seed=args.seed)}

    body = {
        "model": result.model_text(), "cli_models": result.model_text("+"),
        "fitted": result.fitted,
        "split": {"by": "run_info file (recording), simcred.sim.sumo_calibration.halves on the "
                        "10 s episodes",
                  "calibration": _files(fit), "held_out": _files(held)},
        "episode_duration_s": {"calibration": args.duration, "held_out_half": 10.0},
        "objective": "mean over episodes of (NRMSE(gap) + NRMSE(v)) / 2; NRMSE = RMSE / RMS of "
                     "the recorded signal; every 0.1 s step of each episode",
        **halves_out,
        "calibration": result.to_dict(),
        "versions": {"simcred": __version__, "sumo": sumo_version(), "numpy": np.__version__,
                     "python": platform.python_version()},
    }
    document = envelope("sumo_calibration", body, inputs=inputs,
                        options={"model": "IDM", "params": list(result.bounds),
                                 "duration": args.duration,
                                 "max_evaluations": args.max_evaluations, "seed": args.seed})
    args.out.write_text(dumps(document))
    print(f"{result.evaluations} replays in {seconds:.0f} s; fitted {result.model_text()}",
          file=sys.stderr)
    for name, part in halves_out.items():
        print(f"{name:>18}: J default {part['default']['objective']:.4f} -> calibrated "
              f"{part['calibrated']['objective']:.4f}; RMSE gap "
              f"{part['default']['rmse_gap_m']:.2f} -> {part['calibrated']['rmse_gap_m']:.2f} m, "
              f"speed {part['default']['rmse_v_mps']:.3f} -> "
              f"{part['calibrated']['rmse_v_mps']:.3f} m/s", file=sys.stderr)
    print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
