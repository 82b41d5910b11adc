"""Path safety: no file simcred did not write is removed or changed, whatever the path says.

Each scenario builds links, ``..`` paths, ancestors of the working or home directory and outputs
that contain inputs in a sandbox (its own HOME and working directory), runs one command and
checks the exit code and that every file and link that was not written by simcred (outside a
folder holding simcred's marker) is still there with the same bytes (issue 29).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from simcred.cli import run
from simcred.examples import lane_change_sets
from simcred.outputs import MARKER
from simcred.traces import TraceSet

LIBRARY = Path(__file__).parents[2] / "examples" / "contracts" / "figure2.yaml"

COMPARE = ["-f", "y", "--bins", "3", "--permutations", "19", "--baseline", "0", "--seed", "1"]
MATRIX = ["-f", "y", "--bins", "3", "--permutations", "19", "--seed", "1"]
EXAMPLE = ["example", "--runs", "2", "--steps", "4"]


def user_files(root: Path) -> dict[str, bytes | str]:
    """Every file (its bytes) and link (its target) under ``root`` that simcred did not write:
    none inside a folder holding the marker."""
    found: dict[str, bytes | str] = {}
    for folder, dirs, files in os.walk(root):
        here = Path(folder)
        if (here / MARKER).is_file() and not (here / MARKER).is_symlink():
            dirs.clear()
            continue
        for name in files + [d for d in dirs if (here / d).is_symlink()]:
            path = here / name
            key = path.relative_to(root).as_posix()
            found[key] = f"-> {os.readlink(path)}" if path.is_symlink() else path.read_bytes()
    return found


class Sandbox:
    """``home/user`` (HOME, with .bashrc), ``work/proj`` (the cwd), inputs ``data/a`` (a CSV
    directory) and ``data/b.parquet``."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.home = root / "home" / "user"
        self.cwd = root / "work" / "proj"
        self.data = root / "data"
        for folder in (self.home, self.cwd, self.data):
            folder.mkdir(parents=True)
        (self.home / ".bashrc").write_text("alias ll='ls -l'\n")
        (self.cwd / "notes.txt").write_text("my notes\n")
        (root / "work" / "todo.txt").write_text("todo\n")
        a, b = lane_change_sets(runs=12, steps=12, seed=3)
        self.a = a.write(self.data / "a")
        self.b = b.write(self.data / "b.parquet")

    def link(self, name: str, target: Path) -> Path:
        path = self.root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.symlink_to(target)
        return path

    def folder(self, name: str) -> Path:
        """A folder of the user's, with a file in it."""
        path = self.root / name
        path.mkdir(parents=True)
        (path / "mine.txt").write_text("mine\n")
        return path

    def simcred_output(self, name: str) -> Path:
        path = self.root / name
        assert run(["-q", *EXAMPLE, "--out", str(path)]) == 0
        return path

    def monitor(self, library: Path, runs: Path, out: Path | str) -> list[str]:
        return ["monitor", str(library), str(runs), "--setup", "I1=M1,I2=M2a", "--out",
                str(out), "--overwrite"]

    def monitored(self) -> tuple[Path, Path]:
        """A copy of the example library and recorded runs named as its variables."""
        library = self.data / "library.yaml"
        library.write_bytes(LIBRARY.read_bytes())
        runs = TraceSet.from_runs([{"t": [0.0, 0.1, 0.2], "v": [20.0] * 3, "q": [10.0] * 3,
                                    "err": [0.05] * 3}], source="r").write(self.data / "runs")
        return library, runs

    def compare(self, a: Path | str, b: Path | str, out: Path | str) -> list[str]:
        return ["compare", str(a), str(b), *COMPARE, "--out", str(out), "--overwrite"]

    def matrix(self, a: Path | str, b: Path | str, out: Path | str) -> list[str]:
        return ["matrix", str(a), str(b), *MATRIX, "--out", str(out), "--overwrite"]

    def example(self, out: Path | str) -> list[str]:
        return [*EXAMPLE, "--out", str(out), "--overwrite"]

    def convert(self, src: Path | str, dst: Path | str) -> list[str]:
        return ["convert", str(src), str(dst), "--overwrite"]


def _through_parent_link(s: Sandbox) -> list[str]:
    (s.data / "sub").mkdir()
    s.link("ln", s.data / "sub")  # ln/.. is data/, where b.parquet is; as written, the sandbox
    return s.convert(s.b, s.root / "ln" / ".." / "b.parquet")


def _output_holding_an_input(s: Sandbox) -> list[str]:
    out = s.simcred_output("made")
    lane_change_sets(runs=12, steps=12, seed=4)[0].write(out / "copied")
    (out / "copied" / "keep.txt").write_text("a user's file in a copied input\n")
    return s.compare(out / "copied", s.b, out)


def _output_with_a_link_to_user_data(s: Sandbox) -> list[str]:
    out = s.simcred_output("made")
    (out / "data-link").symlink_to(s.data)  # removing the output removes the link, not data
    (out / "home-link").symlink_to(s.home)
    return s.example(out)


def _hard_link(s: Sandbox) -> list[str]:
    os.link(s.b, s.root / "hard.parquet")
    return s.convert(s.b, s.root / "hard.parquet")


def _foreign_partial(s: Sandbox) -> list[str]:
    made = s.simcred_output("made")
    s.folder("made.partial")
    return s.example(made)


def _linked_partial(s: Sandbox) -> list[str]:
    s.link("made.partial", s.folder("precious"))
    return s.example(s.root / "made")


def _linked_partial_resumed(s: Sandbox) -> list[str]:
    s.link("sim.partial", s.folder("precious"))
    return ["simulate", "simplecar", "--runs", "2", "--duration", "4", "--out",
            str(s.root / "sim"), "--resume"]


INPUT = "would overwrite the input"
LINK = "is a symbolic link"
HOME = "holds the working or home directory"
ROOT = "is the root folder"
FOREIGN = "not written by simcred|not a directory simcred made"
#: scenario -> (its command, the exit code, what the refusal says)
SCENARIOS: dict[str, tuple[Callable[[Sandbox], list[str]], int, str | None]] = {
    # inputs through links: the output is an input
    "compare LA B --out A": (lambda s: s.compare(s.link("la", s.a), s.b, s.a), 2, INPUT),
    "compare A B --out LA": (lambda s: s.compare(s.a, s.b, s.link("la", s.a)), 2, LINK),
    "compare A LB --out B (a file)": (lambda s: s.compare(s.a, s.link("lb.parquet", s.b),
                                                          s.b), 2, INPUT),
    "matrix LA B --out A": (lambda s: s.matrix(s.link("la", s.a), s.b, s.a), 2, INPUT),
    "matrix A B --out LD/a (linked parent)": (
        lambda s: s.matrix(s.a, s.b, s.link("ld", s.data) / "a"), 2, INPUT),
    "compare A B --out LD (link to the inputs' folder)": (
        lambda s: s.compare(s.a, s.b, s.link("ld", s.data)), 2, LINK),
    "compare A B --out inside A through a link": (
        lambda s: s.compare(s.a, s.b, s.link("la", s.a) / "sub"), 2, INPUT),
    "convert la.parquet a.parquet": (lambda s: s.convert(s.link("la.parquet", s.b), s.b), 2, INPUT),
    "convert a.parquet la.parquet": (lambda s: s.convert(s.b, s.link("la.parquet", s.b)), 2, LINK),
    "convert through ln/.. (a link's parent)": (_through_parent_link, 2, INPUT),
    "convert to a hard link of the input": (_hard_link, 2, INPUT),
    "compare A B --out A/../a": (lambda s: s.compare(s.a, s.b, s.a / ".." / "a"), 2, INPUT),
    "compare ln/../a B --out A": (
        lambda s: s.compare(s.link("x/ln", s.data / "a") / ".." / "a", s.b, s.a), 2, INPUT),
    "simulate --out a link to an input Parquet": (
        lambda s: ["simulate", "simplecar", "--runs", "2", "--duration", "4", "--out",
                   str(s.link("sim.parquet", s.b)), "--overwrite"], 2, LINK),
    "monitor --out RUNS/run_0.csv through a linked runs folder": (
        lambda s: s.monitor(s.monitored()[0], s.data / "runs",
                            s.link("lr", s.data / "runs") / "run_0.csv"), 2, INPUT),
    "monitor with a linked library --out the library": (
        lambda s: s.monitor(s.link("lib.yaml", s.monitored()[0]), s.data / "runs",
                            s.data / "library.yaml"), 2, INPUT),
    # outputs that would contain an input
    "compare A B --out DATA (holds both inputs)": (lambda s: s.compare(s.a, s.b, s.data), 2, INPUT),
    "compare A B --out the sandbox": (lambda s: s.compare(s.a, s.b, s.root), 2, INPUT),
    "a simcred output that now holds an input": (_output_holding_an_input, 2, INPUT),
    # the working directory, HOME and their ancestors
    "example --out .": (lambda s: s.example("."), 2, HOME),
    "example --out ..": (lambda s: s.example(".."), 2, HOME),
    "example --out L/proj, L a link to the cwd's parent": (
        lambda s: s.example(s.link("l", s.root / "work") / "proj"), 2, HOME),
    "example --out L/.., L a link to the cwd": (
        lambda s: s.example(s.link("l", s.cwd) / ".."), 2, HOME),
    "example --out HOME": (lambda s: s.example(s.home), 2, HOME),
    "example --out homes (holds HOME)": (lambda s: s.example(s.root / "home"), 2, HOME),
    "example --out / ": (lambda s: s.example("/"), 2, ROOT),
    "example --out a link to HOME": (lambda s: s.example(s.link("lh", s.home)), 2, LINK),
    "example --out HOME/../user": (lambda s: s.example(s.home / ".." / "user"), 2, HOME),
    # folders simcred did not write, links as outputs
    "example --out a folder of the user's": (lambda s: s.example(s.folder("mine")), 2, FOREIGN),
    "example --out a dangling link": (
        lambda s: s.example(s.link("gone", s.root / "nope")), 2, LINK),
    "example --out a link to a user's folder": (
        lambda s: s.example(s.link("lm", s.folder("mine"))), 2, LINK),
    "example over a user's OUT.partial": (_foreign_partial, 2, FOREIGN),
    "example over a linked OUT.partial": (_linked_partial, 2, FOREIGN),
    "simulate --resume with a linked OUT.partial": (_linked_partial_resumed, 2, FOREIGN),
    "convert A --out a user's folder": (lambda s: s.convert(s.b, s.folder("mine")), 2, FOREIGN),
    # what --overwrite may replace: simcred's own outputs, links inside them left alone
    "example over a simcred output": (lambda s: s.example(s.simcred_output("made")), 0, None),
    "example over a simcred output with links to user data": (
        _output_with_a_link_to_user_data, 0, None),
    "example --out a new folder through a link to a parent": (
        lambda s: s.example(s.link("lw", s.root / "work") / "new"), 0, None),
}


@pytest.mark.parametrize("name", SCENARIOS)
def test_no_file_simcred_did_not_write_is_removed_or_changed(name, tmp_path, monkeypatch,
                                                             capsys):
    sandbox = Sandbox(tmp_path)
    monkeypatch.setenv("HOME", str(sandbox.home))
    monkeypatch.chdir(sandbox.cwd)
    make, expected, reason = SCENARIOS[name]
    args = make(sandbox)
    before = user_files(tmp_path)
    capsys.readouterr()
    code = run(["-q", *args])
    err = capsys.readouterr().err.strip()
    assert code == expected, err
    if code == 2:
        assert len(err.splitlines()) == 1 and re.search(reason, err), err
    after = user_files(tmp_path)
    assert {k: v for k, v in before.items() if after.get(k) != v} == {}


def test_the_suite_has_at_least_thirty_refusals():
    assert sum(code == 2 for _, code, _ in SCENARIOS.values()) >= 30
