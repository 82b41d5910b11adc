"""A validation file cannot write outside its outputs: a candidate's simulator command carrying
``--out``, ``--overwrite``, ``--resume`` or an output path outside ``DIR/runs/NAME`` is refused
with one line before anything is written, and nothing outside ``DIR`` changes."""

from __future__ import annotations

from pathlib import Path

import pytest
from tests.validate.conftest import write_universe

from simcred.cli import run
from simcred.cli.validate import simulate_candidates
from simcred.validate import read_validation

SIMPLECAR = ["simulate", "simplecar", "--runs", "2", "--duration", "4", "--dt", "2"]


def snapshot(root: Path) -> dict[str, bytes | None]:
    return {p.relative_to(root).as_posix(): p.read_bytes() if p.is_file() else None
            for p in sorted(root.rglob("*"))}


HOSTILE = {
    "--out elsewhere, replaced": ([*SIMPLECAR, "--out", "{victim}", "--overwrite"], "."),
    "--out the project folder": ([*SIMPLECAR, "--out", "{base}", "--overwrite"], "."),
    "--out=": ([*SIMPLECAR, "--out={victim}"], "."),
    "-o": ([*SIMPLECAR, "-o", "{victim}"], "."),
    "--overwrite alone": ([*SIMPLECAR, "--overwrite"], "."),
    "--resume": ([*SIMPLECAR, "--resume"], "."),
    "{out} climbing out": ([*SIMPLECAR, "--out", "{out}/../../.."], "."),
    "{out} as another argument": ([*SIMPLECAR, "--lambda", "{out}"], "."),
    "output climbing out": (SIMPLECAR, "../../../victim"),
    "output absolute": (SIMPLECAR, "{victim}"),
}


@pytest.mark.parametrize("case", HOSTILE)
def test_hostile_simulator_command_is_refused_and_nothing_outside_dir_changes(case, tmp_path,
                                                                              capsys):
    project, victim = tmp_path / "project", tmp_path / "victim"
    project.mkdir()
    victim.mkdir()
    (victim / "notes.txt").write_text("keep me")
    command, output = HOSTILE[case]
    command = [a.replace("{victim}", str(victim)) for a in command]
    candidate = {"simulate": {"command": command, "output": output.replace("{victim}",
                                                                          str(victim))}}
    path = write_universe(project, runs=10, steps=20, candidates={"sim": candidate})
    (project / "notes.txt").write_text("project notes")
    before = snapshot(tmp_path)
    out = tmp_path / "DIR"
    assert run(["-q", "validate", str(path), "--out", str(out), "--overwrite"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "candidates.sim.simulate" in err
    assert snapshot(tmp_path) == before  # DIR not even created


def test_validate_places_the_output_of_a_command_without_out(tmp_path):
    path = write_universe(tmp_path, runs=10, steps=20, candidates={
        "sim": {"simulate": {"command": SIMPLECAR, "output": "."}},
        "legacy": {"simulate": {"command": [*SIMPLECAR, "--out", "{out}"], "output": "."}}})
    spec, base = read_validation(path)
    assert spec.candidates["legacy"].simulate.command == SIMPLECAR  # --out {out}: the default
    made = simulate_candidates(spec, base, tmp_path / "DIR")
    for name in ("sim", "legacy"):
        assert Path(made[name].path).resolve() == (tmp_path / "DIR" / "runs" / name).resolve()
        assert sorted(p.name for p in (tmp_path / "DIR" / "runs" / name).glob("*.csv")) == \
            ["run_00000.csv", "run_00001.csv"]


def test_a_disk_fault_in_a_candidates_simulation_is_exit_74(tmp_path, monkeypatch, capsys):
    """The nested simulate leaves the fault to validate, which reports it once."""
    import errno
    import os

    import pyarrow.csv as pacsv

    def full(table, where, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(where))

    path = write_universe(tmp_path, runs=10, steps=20, candidates={
        "sim": {"simulate": {"command": SIMPLECAR, "output": "."}}})
    monkeypatch.setattr(pacsv, "write_csv", full)
    assert run(["-q", "validate", str(path), "--out", str(tmp_path / "DIR")]) == 74
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no space left" in err
    assert not (tmp_path / "DIR").exists() and not (tmp_path / "DIR.partial").exists()


def test_validate_runs_a_simulator_without_the_cli(tmp_path):
    """The library runs a candidate's simulator command through the simulator registry: the
    CLI is never imported (no re-entry, no global state)."""
    import os
    import subprocess
    import sys

    import simcred

    path = write_universe(tmp_path, runs=10, steps=20, candidates={
        "sim": {"simulate": {"command": SIMPLECAR, "output": "."}}})
    code = (
        "import sys\n"
        "from pathlib import Path\n"
        "from simcred.validate import read_inputs, read_validation, simulate_candidates\n"
        f"spec, base = read_validation({str(path)!r})\n"
        f"made = simulate_candidates(spec, base, Path({str(tmp_path / 'DIR')!r}))\n"
        "inputs = read_inputs(spec, base, made)\n"
        "assert inputs.candidates['sim'].n_runs == 2, inputs.candidates['sim'].n_runs\n"
        "assert not [m for m in sys.modules if m.startswith('simcred.cli')]\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(Path(simcred.__file__).parents[1]), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert done.returncode == 0, done.stderr
