"""simcred's modules import one way: the layer order of docs/architecture.md, checked on the AST.

Run alone: ``python -m pytest tests/test_layers.py``. Every ``import`` / ``from … import`` in
``src/simcred`` (module level, inside functions and under ``TYPE_CHECKING`` alike) is an edge;
an edge is allowed iff it goes to the same package, to a lower layer, or (experiments) as
:data:`EXPERIMENT_USERS` say. Siblings in one layer (compare, contracts, scenario, risk) do not
import each other.
"""

from __future__ import annotations

import ast
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

#: Layer of each top-level unit (``simcred.X``), lowest first. ``simcred`` itself is the root face:
#: it may import the core and io (io registers the TraceSet file formats), nothing imports it
#: from inside the package but the CLI.
#: The core is ordered within itself (0.00 … 0.10), so its modules cannot import in a circle.
CORE = ("_version", "_lazy", "errors", "limits", "data", "_json", "outputs", "seeds", "engine",
        "traces", "kinematics")
LAYERS: dict[str, float] = {
    **{unit: i / 100 for i, unit in enumerate(CORE)},
    "io": 1,
    "compare": 2, "contracts": 2, "scenario": 2, "risk": 2,
    "sim": 3, "examples": 3,
    "reprocess": 4, "study": 4,
    "validate": 4.5,
    "report": 5,
    "paper": 6,
    "cli": 7,
}
ROOT_LAYER = 1  # the package face ``simcred/__init__`` imports the core and io
#: Experiments are leaves: concrete set-ups (the cut-in, the T-junction, the SimpleCar sweep,
#: the lane-change examples) that only the paper runner and the CLI may import.
EXPERIMENTS = ("simcred.sim.experiments", "simcred.examples")
EXPERIMENT_USERS = ("simcred.paper", "simcred.cli")


@dataclass(frozen=True, slots=True)
class Edge:
    importer: str
    imported: str
    line: int

    def __str__(self) -> str:
        return f"{self.importer} imports {self.imported} (line {self.line})"


def module_name(path: Path, src: Path) -> str:
    parts = list(path.relative_to(src).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports(path: Path, src: Path) -> Iterator[Edge]:
    """Every simcred module that ``path`` imports (absolute names; relative imports resolved)."""
    name = module_name(path, src)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            # ``from simcred.x import y``: y may be a module or a name; the package x is imported
            # either way, and a submodule y is at least as constrained (same unit).
            targets = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        for target in targets:
            if target == "simcred" or target.startswith("simcred."):
                yield Edge(name, target, node.lineno)


def _unit(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else None


def _layer(module: str) -> int | None:
    unit = _unit(module)
    if unit is None:
        return ROOT_LAYER
    return LAYERS.get(unit)


def _is_experiment(module: str) -> bool:
    return any(module == e or module.startswith(e + ".") for e in EXPERIMENTS)


def resolve(target: str, known: set[str]) -> str | None:
    """The module ``target`` names: itself, or (``from mod import name``) its module."""
    if target in known or target == "simcred":
        return target
    parent = target.rpartition(".")[0]
    return parent if parent in known and parent != "simcred" else None


def violation(importer: str, imported: str, edge: Edge) -> str | None:
    """Why ``importer`` importing ``imported`` breaks the layer order, or None."""
    if _is_experiment(imported) and not _is_experiment(importer):
        if not importer.startswith(EXPERIMENT_USERS):
            return f"{edge}: experiments are leaves (only paper and cli import them)"
        return None
    if _unit(importer) == _unit(imported):
        return None
    if _unit(imported) is None:
        if _unit(importer) == "cli":
            return None
        return f"{edge}: only the CLI imports the package root (import the module itself)"
    low, high = _layer(imported), _layer(importer)
    if low is None or high is None:
        return f"{edge}: unknown unit (add it to LAYERS in tests/test_layers.py)"
    if low < high or (_unit(importer) is None and low <= ROOT_LAYER):
        return None
    if low == high:
        return f"{edge}: siblings of layer {low:g} do not import each other"
    return (f"{edge}: layer {low:g} ({_unit(imported)}) is above layer {high:g} "
            f"({_unit(importer)})")


def violations(src: Path) -> list[str]:
    """Every import in ``src/simcred`` that breaks the order, one line each."""
    files = sorted((src / "simcred").rglob("*.py"))
    known = {module_name(f, src) for f in files}
    found = {}
    for path in files:
        for edge in imports(path, src):
            imported = resolve(edge.imported, known)
            if imported is None or (edge.importer, imported, edge.line) in found:
                continue
            shown = Edge(edge.importer, imported, edge.line)
            found[edge.importer, imported, edge.line] = violation(edge.importer, imported, shown)
    return [problem for problem in found.values() if problem]


def test_simcred_imports_one_way():
    found = violations(SRC)
    assert not found, "layer violations:\n" + "\n".join(found)


def test_every_unit_has_a_layer():
    units = {p.stem if p.is_file() else p.name for p in (SRC / "simcred").iterdir()
             if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").exists()}
    assert units <= set(LAYERS), f"units without a layer: {sorted(units - set(LAYERS))}"


# -- the test of the test: a copy of the package with one violation injected ----------------------

INJECTIONS = [
    ("simcred/traces.py", "from simcred.io import parquet", "layer 1 (io) is above layer 0"),
    ("simcred/scenario/fit.py", "from simcred.sim import vehicles", "layer 3 (sim) is above"),
    ("simcred/sim/resimulation.py", "from simcred.sim.experiments import cutin",
     "experiments are leaves"),
    ("simcred/reprocess/pipeline.py", "from simcred.report import seed002", "layer 5 (report)"),
    ("simcred/risk/measures.py", "import simcred.scenario.description", "siblings of layer 2"),
    ("simcred/engine.py", "    from simcred import errors", "only the CLI imports the package"),
]


@pytest.mark.parametrize(("target", "line", "message"), INJECTIONS,
                         ids=[i[0].split("/", 1)[1] for i in INJECTIONS])
def test_an_injected_violation_is_found(tmp_path, target, line, message):
    copy = tmp_path / "src"
    shutil.copytree(SRC / "simcred", copy / "simcred",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    path = copy / target
    text = path.read_text()
    injected = f"\n\ndef _injected():\n{line if line.startswith(' ') else '    ' + line}\n"
    path.write_text(text + injected)
    found = sorted(set(violations(copy)) - set(violations(SRC)))  # only what was injected
    assert found and all(message in problem for problem in found), found


def test_relative_imports_are_resolved(tmp_path):
    package = tmp_path / "simcred" / "risk"
    package.mkdir(parents=True)
    (tmp_path / "simcred" / "__init__.py").write_text("")
    (package / "__init__.py").write_text("")
    (package / "ttr.py").write_text("from ..sim import vehicles\nfrom . import measures\n")
    edges = {e.imported for e in imports(package / "ttr.py", tmp_path)}
    assert edges == {"simcred.sim", "simcred.sim.vehicles", "simcred.risk",
                     "simcred.risk.measures"}


# -- faces: every package lists its public API, and every listed name resolves -------------------

FACES = ["simcred.io", "simcred.scenario", "simcred.risk", "simcred.sim", "simcred.reprocess",
         "simcred.report", "simcred.paper", "simcred.kinematics", "simcred.seeds", "simcred.cli"]


@pytest.mark.parametrize("face", FACES)
def test_every_face_lists_names_that_exist(face):
    import importlib

    module = importlib.import_module(face)
    assert module.__all__, face
    missing = [name for name in module.__all__ if getattr(module, name, None) is None]
    assert not missing, f"{face}.__all__ lists missing names {missing}"


# -- tests mirror the package: tests/<package>/test_*.py -----------------------------------------

#: The only test modules at the top of tests/: whole-project checks (this file, test_docs.py),
#: and (allowed for now, to be moved to tests/compare/) the comparison's calibration and oracle
#: suites.
TOP_LEVEL_TESTS = {"test_layers.py", "test_docs.py", "test_calibration.py",
                   "test_compare_oracle.py"}


def test_package_tests_sit_in_their_package_folder():
    tests = Path(__file__).resolve().parent
    top = {p.name for p in tests.glob("test_*.py")}
    assert top <= TOP_LEVEL_TESTS, (f"move {sorted(top - TOP_LEVEL_TESTS)} into "
                                    "tests/<package>/ (git mv)")
