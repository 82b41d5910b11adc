"""The candidates a validation file makes by a simulator command, run as library calls through
the simulator registry (:data:`simcred.sim.registry.SIMULATORS`): no re-entry into the CLI."""

from __future__ import annotations

import shutil
from pathlib import Path

from simcred.errors import SimcredError
from simcred.outputs import Checkpoint, partial_path
from simcred.sim import registry
from simcred.validate.spec import RunsSpec, ValidationSpec


def simulate_candidates(spec: ValidationSpec, base: Path, out: Path,
                        checkpoint: Checkpoint | None = None) -> dict[str, RunsSpec]:
    """Run each candidate's simulator command (``simulate NAME ...``, in-process) into
    ``out/runs/<candidate>`` (the command itself carries no --out, --overwrite or --resume:
    :func:`~simcred.validate.spec.without_placed_output`); the runs it wrote, per candidate.

    Each finished simulation is marked in ``checkpoint``: a resumed validation does not run it
    again (its output was written atomically, so it is complete). A simulator's bad option or
    failure is one line naming the candidate; a disk fault (``OSError``) propagates as it is.
    """
    made = {}
    for index, (name, candidate) in enumerate(spec.candidates.items()):
        if candidate.simulate is None:
            continue
        folder = (out / "runs" / name).resolve()
        made[name] = RunsSpec(path=str(folder / candidate.simulate.output),
                              options=candidate.simulate.options)
        done = f"simulated-{index:04d}"
        if checkpoint is not None and done in checkpoint:
            continue
        for left in (folder, partial_path(folder)):  # an interrupted simulation: start over
            shutil.rmtree(left, ignore_errors=True)
        folder.mkdir(parents=True)
        args = [a.replace("{base}", str(base)) for a in candidate.simulate.command]
        try:
            registry.run(args, folder)  # the only output: the file's own --out was refused
        except SimcredError as exc:
            raise SimcredError(f"candidates.{name}.simulate: 'simcred {' '.join(args)}': "
                               f"{exc}") from None
        if checkpoint is not None:
            checkpoint.save(done, b"")
    return made
