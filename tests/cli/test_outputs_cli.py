"""Every command that writes: atomic outputs, --overwrite, --resume, Ctrl-C and progress.

An existing non-empty output is replaced only with ``--overwrite`` (never merged); a failed or
interrupted command leaves no output that looks complete; an interrupted resumable command keeps
its finished chunks in ``OUT.partial`` and ``--resume`` gives the same bytes as an uninterrupted
run (docs/reliability.md).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from simcred.cli import run
from simcred.engine import Checkpointed, Engine
from simcred.examples import lane_change_sets
from simcred.outputs import Checkpoint, partial_path


def tree(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (or ``root`` itself) by relative name, with its bytes."""
    if root.is_file():
        return {root.name: root.read_bytes()}
    return {p.relative_to(root).as_posix(): p.read_bytes()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def sets(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp("sets")
    a, b = lane_change_sets(runs=30, steps=20, seed=3)
    return a.write(root / "a"), b.write(root / "b.parquet")


def _commands(sets: tuple[Path, Path], out: Path) -> dict[str, list[str]]:
    """Cheap invocations of the commands that write ``out``."""
    a, b = sets
    return {
        "compare": ["compare", str(a), str(b), "-f", "y", "--bins", "3", "--permutations", "19",
                    "--baseline", "0", "--seed", "1", "--out", str(out)],
        "matrix": ["matrix", str(a), str(b), "-f", "y", "--bins", "3", "--permutations", "19",
                   "--seed", "1", "--out", str(out)],
        "example": ["example", "--runs", "3", "--steps", "5", "--out", str(out)],
        "simulate simplecar (csv dir)": ["simulate", "simplecar", "--runs", "4", "--chunk-size",
                                         "2", "--duration", "4", "--out", str(out)],
        "simulate simplecar (parquet)": ["simulate", "simplecar", "--runs", "4", "--duration",
                                         "4", "--out", str(out.with_suffix(".parquet"))],
        "convert": ["convert", str(b), str(out.with_suffix(".parquet"))],
        "convert (csv dir)": ["convert", str(b), str(out)],
    }


CASES = list(_commands((Path("a"), Path("b")), Path("out")))


@pytest.mark.parametrize("name", CASES)
def test_existing_output_is_replaced_only_with_overwrite(name, sets, tmp_path, capsys):
    out = tmp_path / "out"
    args = _commands(sets, out)[name]
    target = Path(args[-1])
    assert run(["-q", *args]) == 0
    first = tree(target)
    if target.is_dir():
        (target / "stale.txt").write_text("from before")
    capsys.readouterr()
    assert run(["-q", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--overwrite" in err, err
    assert run(["-q", *args, "--overwrite"]) == 0
    assert tree(target) == first  # replaced, never merged: the stale file is gone
    assert not partial_path(target).exists()


def test_failure_leaves_no_output_that_looks_complete(sets, tmp_path, monkeypatch, capsys):
    import simcred.report.figures as figures

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(figures, "state_map", broken)
    out = tmp_path / "out"
    assert run(["-q", *_commands(sets, out)["compare"]]) == 70
    assert not out.exists() and not partial_path(out).exists()
    assert "disk full" in capsys.readouterr().err


def _simulate(out: Path, *extra: str) -> list[str]:
    return ["-q", "simulate", "simplecar", "--runs", "6", "--chunk-size", "1", "--duration",
            "6", "--seed", "4", "--out", str(out), *extra]


def _interrupted_run(monkeypatch, out: Path, chunk: int) -> None:
    """``simulate simplecar`` into ``out`` stopped by Ctrl-C when chunk ``chunk`` starts
    (exit 130, the chunks before it checkpointed); the real simulation restored afterwards."""
    from simcred.sim.experiments import simplecar_sweep

    real = simplecar_sweep.simulate

    def interrupted(indices, seed, **params):
        if indices[0] == chunk:
            raise KeyboardInterrupt
        return real(indices, seed, **params)

    monkeypatch.setattr(simplecar_sweep, "simulate", interrupted)
    assert run(_simulate(out)) == 130
    monkeypatch.setattr(simplecar_sweep, "simulate", real)


def test_ctrl_c_keeps_finished_chunks_and_resume_gives_the_same_bytes(tmp_path, monkeypatch,
                                                                      capsys):
    from simcred.sim.experiments import simplecar_sweep

    assert run(_simulate(tmp_path / "whole")) == 0
    expected = tree(tmp_path / "whole")
    real, calls = simplecar_sweep.simulate, []

    def interrupted_at_the_fourth_chunk(indices, seed, **params):
        calls.append(list(indices))
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(indices, seed, **params)

    monkeypatch.setattr(simplecar_sweep, "simulate", interrupted_at_the_fourth_chunk)
    out = tmp_path / "out"
    capsys.readouterr()
    assert run(_simulate(out)) == 130
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert f"3 finished chunks kept in {partial_path(out)}" in err and "--resume" in err
    assert not out.exists()
    assert run(_simulate(out)) == 2  # neither resumed nor overwritten: says how to go on
    assert "--resume" in capsys.readouterr().err
    calls.clear()
    assert run(_simulate(out, "--resume")) == 0
    assert calls == [[3], [4], [5]]  # only the missing chunks ran again
    assert tree(out) == expected and not partial_path(out).exists()


def test_resume_refuses_other_options(tmp_path, monkeypatch, capsys):
    out = tmp_path / "out"
    _interrupted_run(monkeypatch, out, 2)
    capsys.readouterr()
    assert run([*_simulate(out, "--resume"), "--lambda", "0.9"]) == 2
    err = capsys.readouterr().err
    assert "other options" in err and "--overwrite" in err
    assert run([*_simulate(out, "--overwrite"), "--lambda", "0.9"]) == 0


def test_ctrl_c_without_checkpoints_keeps_nothing(sets, tmp_path, monkeypatch, capsys):
    import simcred.report.figures as figures

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(figures, "state_map", interrupted)
    out = tmp_path / "out"
    assert run(["-q", *_commands(sets, out)["compare"]]) == 130
    err = capsys.readouterr().err.strip()
    assert err.endswith(f"nothing kept, {out} unchanged") and len(err.splitlines()) == 1
    assert not out.exists() and not partial_path(out).exists()


def test_progress_is_a_plain_log_off_a_terminal(sets, tmp_path, capsys):
    """Not on a terminal (pytest captures): one line per step on stderr, the elapsed time at
    the end; stdout holds only the JSON."""
    assert run(["matrix", *map(str, sets), "-f", "y", "--bins", "3", "--permutations", "19",
                "--seed", "1", "--out", str(tmp_path / "m"), "--json"]) == 0
    captured = capsys.readouterr()
    json.loads(captured.out)
    lines = captured.err.strip().splitlines()
    assert lines[0] == "comparing pairs: 1/1"
    assert lines[-1].startswith("done in ") and lines[-1].endswith(" s")


def test_checkpointed_engine_computes_only_missing_tasks(tmp_path):
    store = Checkpoint(tmp_path)
    seen, failing = [], [True]

    def square(x):
        seen.append(x)
        if x == 3 and failing[0]:
            raise RuntimeError("worker lost")
        return x * x

    with pytest.raises(RuntimeError):
        Checkpointed(Engine(), store).map(square, [0, 1, 2, 3, 4])
    assert store.keys() == ["map000-000000", "map000-000001", "map000-000002"]
    seen.clear()
    failing[0] = False
    again = Checkpointed(Engine(), store)
    assert again.map(square, [0, 1, 2, 3, 4]) == [0, 1, 4, 9, 16]
    assert seen == [3, 4] and (again.done, again.total) == (5, 5)
    assert again.map(square, [5]) == [25]  # the next map call has its own keys
    assert "map001-000000" in store


def test_matrix_resumes_after_ctrl_c_with_the_same_bytes(sets, tmp_path, monkeypatch, capsys):
    """Pairs are checkpointed; without --seed the entropy drawn first is kept for the resume."""
    import simcred.compare.pairwise as pairwise

    a, b = sets
    args = ["-q", "matrix", str(a), str(b), str(a), "--names", "a,b,a2", "-f", "y", "--bins",
            "3", "--permutations", "19", "--out", str(tmp_path / "m")]
    real, calls = pairwise._compare_sorted, []  # the runs test's pairs (from sorted sets)

    def interrupted_at_the_third_pair(pair):
        calls.append((pair[0].prepared.info.source, pair[1].prepared.info.source))
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(pair)

    monkeypatch.setattr(pairwise, "_compare_sorted", interrupted_at_the_third_pair)
    assert run(args) == 130
    assert "2 finished chunks kept" in capsys.readouterr().err
    calls.clear()
    assert run([*args, "--resume"]) == 0
    assert calls == [(str(b), str(a))]  # the one pair left: (b, a2)
    monkeypatch.setattr(pairwise, "_compare_sorted", real)
    seed = json.loads((tmp_path / "m" / "matrix.json").read_text())["options"]["seed"]
    assert run([*args[:-2], "--seed", str(seed), "--out", str(tmp_path / "whole")]) == 0
    assert tree(tmp_path / "m") == tree(tmp_path / "whole")


@pytest.mark.slow
def test_vary_resumes_after_ctrl_c_with_the_same_bytes(tmp_path, monkeypatch, capsys):
    import simcred.reprocess.vary as vary

    assert run(["-q", "simulate", "cutin", "--out", str(tmp_path / "m")]) == 0
    assert run(["-q", "reprocess", str(tmp_path / "m"), "--out", str(tmp_path / "r"),
                "--no-scenario-based"]) == 0
    description = tmp_path / "r" / "descriptions" / "fit_GT.json"

    def args(out: str, *extra: str) -> list[str]:
        return ["-q", "vary", str(description), "-n", "60", "--seed", "2", "--out",
                str(tmp_path / out), *extra]

    assert run(args("whole")) == 0
    real, calls = vary._resimulate_chunk, []

    def interrupted_at_the_third_chunk(job):
        calls.append(job[0])
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(job)

    monkeypatch.setattr(vary, "_resimulate_chunk", interrupted_at_the_third_chunk)
    capsys.readouterr()
    assert run(args("v")) == 130
    err = capsys.readouterr().err  # 2 chunks generating variations, 2 of 3 resimulating them
    assert "4 finished chunks kept" in err and "(current step 2/3)" in err
    calls.clear()
    assert run(args("v", "--resume")) == 0
    assert len(calls) == 1  # the chunk left
    assert tree(tmp_path / "v") == tree(tmp_path / "whole")


@pytest.mark.slow
def test_study_resumes_after_ctrl_c_with_the_same_bytes(tmp_path, monkeypatch, capsys):
    """The SUMO replays are checkpointed per chunk; the resumed study equals an uninterrupted one
    (findings, tables, comparisons and figures)."""
    import simcred.sim.sumo as sumo

    def args(out: str, *extra: str) -> list[str]:
        return ["-q", "study", "car-following", "--models", "IDM,Krauss", "--max-episodes", "60",
                "--permutations", "99", "--min-runs", "5", "--seed", "2",
                "--out", str(tmp_path / out), *extra]

    assert run(args("whole")) == 0
    real, calls = sumo._simulate_chunk, []  # 60 episodes in chunks of 50: 2 chunks per model

    def interrupted_at_the_third_chunk(task):
        calls.append(task[2][0])
        if len(calls) == 3:
            raise KeyboardInterrupt
        return real(task)

    monkeypatch.setattr(sumo, "_simulate_chunk", interrupted_at_the_third_chunk)
    capsys.readouterr()
    assert run(args("s")) == 130
    assert "2 finished chunks kept" in capsys.readouterr().err
    calls.clear()
    assert run(args("s", "--resume")) == 0
    assert len(calls) == 2  # the interrupted chunk and the one after it
    assert tree(tmp_path / "s") == tree(tmp_path / "whole")


@pytest.mark.slow
def test_validate_resumes_after_ctrl_c_with_the_same_bytes(tmp_path, monkeypatch, capsys):
    """Example (a) at a smaller test size: interrupted while the second candidate simulates, the
    resumed validation simulates only that one and those after it and writes the bytes of an
    uninterrupted run."""
    import simcred.sim.sumo as sumo

    base = tmp_path / "base"
    assert run(["-q", "data", "openacc", "--follower", "human", "--out",
                str(base / "human.parquet")]) == 0
    example = Path(__file__).parents[2] / "examples" / "validate" / "car_following"
    text = (example / "validation.yaml").read_text()
    text = text.replace("permutations: 199", "permutations: 99")
    assert "permutations: 99" in text  # the response comparison has no baseline option
    (base / "validation.yaml").write_text(text)

    def args(out: str, *extra: str) -> list[str]:
        return ["-q", "validate", str(base / "validation.yaml"), "--out", str(tmp_path / out),
                *extra]

    whole = run(args("whole"))
    assert whole == 1  # the shipped example's verdict: SUMO's defaults are not valid
    document = json.loads((tmp_path / "whole" / "verdict.json").read_text())
    order = [r["candidate"] for r in document["ranking"]]
    # the calibrated IDM ranks above the default IDM, Krauss last; the reference halves'
    # own range (humans among themselves) is reported beside them
    assert order.index("idm_calibrated") < order.index("idm") < order.index("krauss"), order
    halves = next(r for r in document["ranking"] if r["candidate"] == "reference halves")
    assert halves["interval"] is not None and halves["interval"][0] <= halves["score"]
    real, models = sumo._simulate_chunk, []

    def interrupted_in_krauss(task):
        models.append(task[0].name)
        if task[0].name == "Krauss":
            raise KeyboardInterrupt
        return real(task)

    monkeypatch.setattr(sumo, "_simulate_chunk", interrupted_in_krauss)
    capsys.readouterr()
    assert run(args("v")) == 130
    err = capsys.readouterr().err.strip()
    assert "IDM" in models and "kept" in err
    assert len(err.splitlines()) == 1, err  # the inner simulate does not print its own line
    models.clear()
    monkeypatch.setattr(sumo, "_simulate_chunk", lambda task: models.append(task[0].name)
                        or real(task))
    assert run(args("v", "--resume")) == whole
    # IDM's finished simulation was kept; Krauss and the candidates after it (idm_calibrated)
    # simulate on resume
    assert "IDM" not in models and "Krauss" in models
    assert tree(tmp_path / "v") == tree(tmp_path / "whole")


def test_a_refused_resume_keeps_every_checkpoint(tmp_path, monkeypatch, capsys):
    """Other options: refused with one line saying how to go on, every finished chunk kept;
    the same --out typed relative instead of absolute resumes."""
    assert run(_simulate(tmp_path / "whole")) == 0
    expected = tree(tmp_path / "whole")
    out = tmp_path / "out"
    _interrupted_run(monkeypatch, out, 4)
    checkpoints = partial_path(out) / "checkpoints"
    kept = tree(checkpoints)
    assert len([k for k in kept if k.startswith("map")]) == 4
    capsys.readouterr()
    assert run([*_simulate(out, "--resume"), "--lambda", "0.9"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "4 finished pieces are kept" in err
    assert "--resume" in err and "job.json" in err
    assert tree(checkpoints) == kept  # nothing removed
    monkeypatch.chdir(tmp_path)
    assert run(_simulate(Path("out"), "--resume")) == 0  # relative now, absolute before
    assert tree(out) == expected
