"""Calibrate SUMO's IDM to half of the OpenACC human episodes; judge it on the other half.

The candidate ``idm_calibrated`` of ``validation.yaml`` was made with this script.

* Episodes: the human following episodes of OpenACC (``human.parquet``, see ``make_runs.py``;
  609 episodes of 10 s at 0.1 s from four recording files of 2019-10-09).
* Split (declared before fitting): by recording file, :func:`simcred.sim.sumo_calibration.halves`
  — files largest first, each into the half with fewer episodes so far. Calibration half:
  ``handling_part22`` + ``handling_part40`` (282 episodes); held out: ``handling_part35`` +
  ``handling_part26`` (327 episodes). No recording, hence no stretch of driving, is in both.
* Fitted: IDM's ``tau``, ``accel``, ``decel``, ``minGap`` within the default bounds of
  :data:`~simcred.sim.sumo_calibration.PARAMETERS`, from SUMO's defaults (1.0 s, 2.6 m/s²,
  4.5 m/s², 2.5 m); everything else as in ``simcred simulate sumo-following`` (IDM ignores the
  seed; seed 0 is recorded anyway).
* Objective: mean over episodes of (NRMSE(gap) + NRMSE(v)) / 2, every step of the 0.1 s replay
  (module doc of :mod:`simcred.sim.sumo_calibration`), Nelder–Mead, at most 300 replays of the
  calibration half (~1.4 s each on one core).

Writes ``idm_calibrated.json`` next to this script (fitted values, bounds, the split's files and
run counts, the objective before/after on both halves, the search's facts, versions; no times,
so a rerun writes the same bytes). Usage::

    python examples/validate/car_following/calibrate_idm.py            # ~5 min
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
from simcred.io.openacc import HUMAN, read_openacc
from simcred.sim.sumo import sumo_version
from simcred.sim.sumo_calibration import calibrate, evaluate, halves
from simcred.traces import RUN_INFO, TraceSet, take

HERE = Path(__file__).parent


def _subset(traces: TraceSet, runs: list[str]) -> TraceSet:
    index = {r: i for i, r in enumerate(traces.run_ids)}
    return take(traces, [index[r] for r in runs])


def _files(traces: TraceSet) -> dict[str, int]:
    info = traces.metadata[RUN_INFO]
    names = [info[r]["file"] for r in traces.run_ids]
    return {f: names.count(f) for f in sorted(set(names))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=HERE / "human.parquet",
                        help="human episodes (default: human.parquet here, else read OpenACC)")
    parser.add_argument("--out", type=Path, default=HERE / "idm_calibrated.json")
    parser.add_argument("--max-evaluations", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    human = TraceSet.read(args.data) if args.data.exists() else read_openacc(follower=HUMAN)
    first, second = halves(human, by="file")
    fit, held = _subset(human, first), _subset(human, second)
    print(f"calibration half {_files(fit)}; held out {_files(held)}", file=sys.stderr)

    started = time.perf_counter()

    def log(count: int, values: dict, value: float) -> None:
        shown = ", ".join(f"{k}={v:.3f}" for k, v in values.items())
        print(f"  {count:3d}  J={value:.5f}  {shown}  ({time.perf_counter() - started:.0f} s)",
              file=sys.stderr)

    result = calibrate(fit, "IDM", seed=args.seed, max_evaluations=args.max_evaluations, log=log)
    seconds = time.perf_counter() - started
    held_default = evaluate(held, result.start, seed=args.seed)
    held_fitted = evaluate(held, result.model, seed=args.seed)

    body = {
        "model": result.model_text(), "cli_models": result.model_text("+"),
        "fitted": result.fitted,
        "split": {"by": "run_info file (recording), simcred.sim.sumo_calibration.halves",
                  "calibration": _files(fit), "held_out": _files(held)},
        "objective": "mean over episodes of (NRMSE(gap) + NRMSE(v)) / 2; NRMSE = RMSE / RMS of "
                     "the recorded signal; every 0.1 s step of each 10 s episode",
        "calibration_half": {"default": result.before, "calibrated": result.after},
        "held_out_half": {"default": held_default, "calibrated": held_fitted},
        "calibration": result.to_dict(),
        "versions": {"simcred": __version__, "sumo": sumo_version(), "numpy": np.__version__,
                     "python": platform.python_version()},
    }
    document = envelope("sumo_calibration", body,
                        inputs={"episodes": human.digest()},
                        options={"model": "IDM", "params": list(result.bounds),
                                 "max_evaluations": args.max_evaluations, "seed": args.seed})
    args.out.write_text(dumps(document))
    print(f"{result.evaluations} replays in {seconds:.0f} s; fitted {result.model_text()}",
          file=sys.stderr)
    for name, part in (("calibration", body["calibration_half"]),
                       ("held out", body["held_out_half"])):
        print(f"{name:>11}: J default {part['default']['objective']:.4f} -> calibrated "
              f"{part['calibrated']['objective']:.4f}; RMSE gap "
              f"{part['default']['rmse_gap_m']:.2f} -> {part['calibrated']['rmse_gap_m']:.2f} m, "
              f"speed {part['default']['rmse_v_mps']:.3f} -> "
              f"{part['calibrated']['rmse_v_mps']:.3f} m/s", file=sys.stderr)
    print(f"wrote {args.out}", file=sys.stderr)


if __name__ == "__main__":
    main()
