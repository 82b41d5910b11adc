"""Kill tests of the resumable commands: each killed with SIGKILL once 0, 1, 2, half, all but
one and all of its chunks are checkpointed (the last while the output is being written), then
run again with ``--resume``: the same bytes as an uninterrupted run every time, and no output
that looks complete meanwhile (issue 29; the shared loop: tests/killing.py; ``paper 000`` is
also killed at 5 seeded moments: tests/paper/test_kill_resume.py)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
import typer
import yaml

from helpers import leaf_commands
from killing import kill_and_resume, kill_points, run_whole
from simcred.cli import app, run
from simcred.examples import lane_change_sets
from simcred.io.openacc import HUMAN, read_openacc
from simcred.traces import take


def _sets(root: Path) -> list[str]:
    """Four small trace sets for ``matrix`` (six pairs)."""
    paths = []
    for seed in range(2):
        a, b = lane_change_sets(runs=20, steps=15, seed=seed)
        paths += [str(a.write(root / f"a{seed}")), str(b.write(root / f"b{seed}.parquet"))]
    return paths


def _human(root: Path) -> Path:
    """31 of OpenACC's human car-following episodes (every 20th)."""
    human = read_openacc(follower=HUMAN)
    return take(human, list(range(0, human.n_runs, 20))).write(root / "human.parquet")


def _description(root: Path) -> Path:
    """The reprocessed cut-in's scenario description (fit to GT), the input of ``vary``."""
    for argv in (["simulate", "cutin", "--seed", "0", "--out", str(root / "measurement")],
                 ["reprocess", str(root / "measurement"), "--out", str(root / "reprocessed")]):
        assert run(["--quiet", *argv]) == 0, argv
    return root / "reprocessed" / "descriptions" / "fit_GT.json"


#: Six candidates, each simulated by ``simulate sumo-following`` run inside ``validate`` (one
#: checkpoint per finished candidate simulation).
MODELS = ("Krauss", "IDM", "EIDM", "ACC", "W99", "KraussPS")


def _validation(root: Path) -> Path:
    _human(root)
    document = {
        "test_case": {"conditions": "10 <= v_leader <= 20", "tolerance": {"v": 0.1}},
        "reference": {"path": "human.parquet"},
        "candidates": {m.lower(): {"simulate": {
            "command": ["simulate", "sumo-following", "{base}/human.parquet", "--models", m,
                        "--chunk-size", "16"], "output": f"{m}.parquet"}} for m in MODELS},
        "features": ["gap", "v", "v_leader"], "inputs": ["v_leader"],
        "conditions": {"v_leader": {"unit": "m/s", "edges": [10, 15, 20]}},
        "comparison": {"bins": 3, "permutations": 99, "bootstrap": 100, "resample": 0.5},
        "min_data": {"runs": 5, "samples": 100}, "segments": {"min_length": 25},
    }
    path = root / "validation.yaml"
    path.write_text(yaml.safe_dump(document))
    return path


#: command -> (arguments before --out given the inputs' folder, chunks it checkpoints)
COMMANDS: dict[str, tuple[Callable[[Path], list[str]], int]] = {
    "simulate tjunction (Parquet)": (lambda root: [
        "simulate", "tjunction", "--runs", "24", "--chunk-size", "3", "--seed", "5"], 8),
    "simulate simplecar (CSV directory)": (lambda root: [
        "simulate", "simplecar", "--runs", "12", "--chunk-size", "2", "--duration", "400",
        "--dt", "0.5", "--seed", "5"], 6),
    "matrix": (lambda root: [
        "matrix", *_sets(root), "-f", "y", "--bins", "3", "--permutations", "199", "--seed",
        "2"], 6),
    # 31 episodes x 2 models in chunks of 5: 14 chunks
    "simulate sumo-following": (lambda root: [
        "simulate", "sumo-following", str(_human(root)), "--models", "IDM,Krauss",
        "--chunk-size", "5", "--seed", "2"], 14),
    # 110 variations: 3 chunks generated (50 each), the original + 3 chunks resimulated
    "vary": (lambda root: ["vary", str(_description(root)), "-n", "110", "--seed", "2"], 7),
    # 3 models x 60 episodes in chunks of 50: 6 chunks of SUMO replays
    "study car-following": (lambda root: [
        "study", "car-following", "--models", "IDM,Krauss,EIDM", "--max-episodes", "60",
        "--permutations", "99", "--tolerance", "v=0.1", "--min-runs", "5", "--seed", "2"], 6),
    # 6 candidate simulations; the verdict's exit code (0, 1 or 3) must be the same too
    "validate": (lambda root: [str(x) for x in ("validate", _validation(root))], 6),
    # paper 000 at --runs 2: 602 chunks (campaigns and compared pairs)
    "paper 000": (lambda root: ["paper", "000", "--runs", "2", "--seed", "3"], 602),
    # paper 002: 4 reprocessings (the drive; delay only, offset only, the held-out drive), the
    # 20 variations generated (1 chunk), the original and the variations resimulated (2)
    "paper 002": (lambda root: ["paper", "002", "--variations", "20", "--seed", "3"], 7),
    # paper 000 (602 chunks), then paper 002 (7 chunks: the kills at 608 and 609 land in it),
    # then paper 003 (no chunks)
    "paper all": (lambda root: [
        "paper", "all", "--runs", "2", "--variations", "20", "--seed", "3"], 609),
}
SUFFIX = {"simulate tjunction (Parquet)": ".parquet"}
#: Exit codes of a complete run besides 0 (validate: 1 not valid, 3 inconclusive).
CODES = {"validate": (0, 1, 3)}
CASES = [(name, k) for name, (_, total) in COMMANDS.items() for k in kill_points(total)]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> Callable[[str], tuple[list[str], tuple]]:
    """Per command (made when first asked for): its arguments, and the exit code and files of
    an uninterrupted run."""
    done: dict[str, tuple[list[str], tuple]] = {}

    def get(name: str) -> tuple[list[str], tuple]:
        if name not in done:
            root = tmp_path_factory.mktemp("inputs")
            args = COMMANDS[name][0](root)
            out = root / f"whole{SUFFIX.get(name, '')}"
            done[name] = args, run_whole(args, out, CODES.get(name, (0,)))
        return done[name]

    return get


@pytest.mark.slow
@pytest.mark.parametrize(("name", "chunks"), CASES, ids=[f"{n}-{k}" for n, k in CASES])
def test_killed_and_resumed_is_byte_identical(name, chunks, uninterrupted, tmp_path):
    args, expected = uninterrupted(name)
    out = tmp_path / f"out{SUFFIX.get(name, '')}"
    kill_and_resume(args, out, chunks, COMMANDS[name][1], expected)


def test_every_command_is_killed_at_six_points_at_least():
    assert all(len(kill_points(total)) >= 6 for _, total in COMMANDS.values())


def test_every_resumable_command_has_a_kill_test():
    resumable = {" ".join(path) for path, command in leaf_commands(typer.main.get_command(app))
                 if any("--resume" in getattr(p, "opts", ()) for p in command.params)}
    names = {name.split(" (")[0] for name in COMMANDS}
    missing = resumable - names
    assert not missing, f"add a kill test for {sorted(missing)}"
