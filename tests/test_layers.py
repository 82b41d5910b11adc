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
CORE = ("_version", "_lazy", "_display", "errors", "limits", "data", "_json", "_xml", "outputs",
        "seeds", "engine", "traces", "kinematics")
LAYERS: dict[str, float] = {
    **{unit: i / 100 for i, unit in enumerate(CORE)},
    "io": 1,
    "compare": 2, "contracts": 2, "scenario": 2, "risk": 2,
    "regions": 2.5,  # the per-region engine of study and validate (compare + contracts)
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
#: ``simcred.sim.registry`` names the simulators ``simcred simulate`` and ``validate`` run (issue
#: 27: one registry instead of validate re-entering the CLI), so it imports the experiments too.
EXPERIMENT_USERS = ("simcred.paper", "simcred.cli", "simcred.sim.registry")


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
            return (f"{edge}: experiments are leaves (only paper, cli and the simulator "
                    "registry import them)")
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
    ("simcred/reprocess/pipeline.py", "from simcred.report import reprocessing",
     "layer 5 (report)"),
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
         "simcred.regions", "simcred.report", "simcred.paper", "simcred.kinematics",
         "simcred.seeds", "simcred.cli"]


@pytest.mark.parametrize("face", FACES)
def test_every_face_lists_names_that_exist(face):
    import importlib

    module = importlib.import_module(face)
    assert module.__all__, face
    missing = [name for name in module.__all__ if getattr(module, name, None) is None]
    assert not missing, f"{face}.__all__ lists missing names {missing}"


# -- tests mirror the package: tests/<package>/test_*.py -----------------------------------------

#: The only test modules at the top of tests/: whole-project checks (this file, test_docs.py,
#: test_wheel_install.py), and (allowed for now, to be moved to tests/compare/) the comparison's
#: calibration and oracle suites.
TOP_LEVEL_TESTS = {"test_layers.py", "test_docs.py", "test_wheel_install.py",
                   "test_calibration.py", "test_compare_oracle.py"}


def test_package_tests_sit_in_their_package_folder():
    tests = Path(__file__).resolve().parent
    top = {p.name for p in tests.glob("test_*.py")}
    assert top <= TOP_LEVEL_TESTS, (f"move {sorted(top - TOP_LEVEL_TESTS)} into "
                                    "tests/<package>/ (git mv)")


# -- nothing imports the CLI ---------------------------------------------------------------------

#: Modules outside ``simcred.cli`` that may import it: the ``python -m simcred`` entry (none yet).
CLI_IMPORTERS = ("simcred.__main__",)


def cli_imports(src: Path) -> list[str]:
    """Every import of ``simcred.cli`` from a module outside it (the library never re-enters the
    command line: a command calls the library, not the other way round)."""
    files = sorted((src / "simcred").rglob("*.py"))
    known = {module_name(f, src) for f in files}
    found = set()
    for path in files:
        for edge in imports(path, src):
            imported = resolve(edge.imported, known)
            if (imported is not None and _unit(imported) == "cli" and _unit(edge.importer) != "cli"
                    and edge.importer not in CLI_IMPORTERS):
                found.add(f"{Edge(edge.importer, imported, edge.line)}: only the CLI imports "
                          "simcred.cli")
    return sorted(found)


def test_no_package_imports_the_cli():
    found = cli_imports(SRC)
    assert not found, "\n".join(found)


# -- no module-level mutable state outside engine and outputs ------------------------------------

#: Where process state belongs: the engine (workers, shared values) and outputs (writing).
STATEFUL = ("simcred.engine", "simcred.outputs")
#: Known exceptions, each (module, name): not to be added to (docs/architecture.md says why).
STATE_ALLOWED = {
    # The slot where simcred.io registers TraceSet's file formats (the core must not import io;
    # docs/architecture.md "TraceSet files without traces → io"): a registry, set once at import.
    ("simcred.traces", "_handlers"),
}
_MUTATORS = {"append", "extend", "insert", "remove", "pop", "popitem", "clear", "update",
             "setdefault", "add", "discard", "difference_update", "intersection_update",
             "symmetric_difference_update", "sort", "reverse", "appendleft", "extendleft"}
_CONTAINERS = {"list", "dict", "set", "defaultdict", "OrderedDict", "Counter", "deque",
               "bytearray"}


def _is_container(value: ast.expr | None) -> bool:
    """A list/dict/set display or comprehension, or a call of a container type."""
    if isinstance(value, (ast.List, ast.Dict, ast.Set, ast.ListComp, ast.DictComp, ast.SetComp)):
        return True
    if isinstance(value, ast.Call):
        func = value.func
        name = func.id if isinstance(func, ast.Name) else getattr(func, "attr", None)
        return name in _CONTAINERS
    return False


def _containers(tree: ast.Module) -> set[str]:
    """Names the module body binds to a mutable container."""
    names = set()
    for node in tree.body:
        if isinstance(node, ast.Assign) and _is_container(node.value):
            names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
        elif (isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name)
              and _is_container(node.value)):
            names.add(node.target.id)
    return names


def _mutated(node: ast.AST, containers: set[str]) -> Iterator[tuple[str, str]]:
    """(name, how) for every change of module state in ``node``."""
    if isinstance(node, ast.Global):
        yield from ((name, "declared global") for name in node.names)
    elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
          and isinstance(node.func.value, ast.Name) and node.func.value.id in containers
          and node.func.attr in _MUTATORS):
        yield node.func.value.id, f".{node.func.attr}()"
    elif isinstance(node, (ast.Assign, ast.AugAssign, ast.Delete)):
        targets = [node.target] if isinstance(node, ast.AugAssign) else node.targets
        for target in targets:
            if (isinstance(target, ast.Subscript) and isinstance(target.value, ast.Name)
                    and target.value.id in containers):
                yield target.value.id, "item set or deleted"


def module_state(src: Path) -> list[str]:
    """Every module-level name (outside :data:`STATEFUL`) that is a mutated container or is
    declared ``global``, one line each, as ``module.name``."""
    found = {}
    for path in sorted((src / "simcred").rglob("*.py")):
        module = module_name(path, src)
        if module in STATEFUL:
            continue
        tree = ast.parse(path.read_text(), str(path))
        containers = _containers(tree)
        for node in ast.walk(tree):
            for name, how in _mutated(node, containers):
                found.setdefault((module, name), f"{module}.{name} (line {node.lineno}: {how})")
    return [line for key, line in sorted(found.items()) if key not in STATE_ALLOWED]


def test_no_module_level_mutable_state_outside_engine_and_outputs():
    found = module_state(SRC)
    assert not found, ("module-level mutable state (keep it in an object, or in engine/outputs):"
                       "\n" + "\n".join(found))


def test_the_state_allow_list_names_only_current_offenders():
    """An entry whose offence is gone must leave the allow-list (it is a to-do list)."""
    still = set()
    for module, name in STATE_ALLOWED:
        path = SRC / Path(*module.split(".")).with_suffix(".py")
        tree = ast.parse(path.read_text())
        containers = _containers(tree)
        if any(n == name for node in ast.walk(tree) for n, _ in _mutated(node, containers)):
            still.add((module, name))
    assert still == STATE_ALLOWED, f"fixed, remove: {sorted(STATE_ALLOWED - still)}"


MORE_INJECTIONS = [
    ("simcred/validate/loop.py", "from simcred.cli import run", cli_imports,
     "only the CLI imports simcred.cli"),
    ("simcred/paper/all.py", "import simcred.cli._app", cli_imports,
     "only the CLI imports simcred.cli"),
    ("simcred/compare/result.py", "_CACHE: dict = {}\n\ndef _injected(key):\n    _CACHE[key] = 1",
     module_state, "_CACHE (line"),
    ("simcred/risk/measures.py", "_SEEN = []\n\ndef _injected(x):\n    _SEEN.append(x)",
     module_state, "_SEEN (line"),
    ("simcred/io/parquet.py", "_count = 0\n\ndef _injected():\n    global _count\n    _count = 1",
     module_state, "declared global"),
]


@pytest.mark.parametrize(("target", "code", "rule", "message"), MORE_INJECTIONS,
                         ids=[f"{i[2].__name__}-{i[0].split('/', 1)[1]}" for i in MORE_INJECTIONS])
def test_an_injected_cli_import_or_module_state_is_found(tmp_path, target, code, rule, message):
    copy = tmp_path / "src"
    shutil.copytree(SRC / "simcred", copy / "simcred",
                    ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    path = copy / target
    body = code if "\n" in code else f"def _injected():\n    {code}"
    path.write_text(path.read_text() + "\n\n" + body + "\n")
    found = sorted(set(rule(copy)) - set(rule(SRC)))
    assert found and all(message in problem for problem in found), found


# -- sizes: modules under 500 lines, function bodies under 60 ---------------------------------

MAX_MODULE_LINES, MAX_BODY_LINES = 500, 60


def _body_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Lines of a function's body without its docstring."""
    body = node.body
    docstring = isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
        and isinstance(body[0].value.value, str)
    first = body[1] if docstring and len(body) > 1 else body[0]
    return node.end_lineno - first.lineno + 1


def test_modules_and_functions_stay_short():
    long_modules, long_functions = [], []
    for path in sorted((SRC / "simcred").rglob("*.py")):
        text = path.read_text(encoding="utf-8")
        name = path.relative_to(SRC).as_posix()
        if text.count("\n") > MAX_MODULE_LINES:
            long_modules.append(f"{name}: {text.count(chr(10))} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef) \
                    and _body_lines(node) > MAX_BODY_LINES:
                long_functions.append(f"{name}:{node.lineno} {node.name}: {_body_lines(node)}")
    assert not long_modules, long_modules
    assert not long_functions, long_functions


def test_every_class_name_names_one_class():
    """One class per name (issue 27: ``Status``, ``Sensor``, ``Campaign``, ``Recording`` and
    ``Layout`` each named two or three different classes)."""
    where: dict[str, list[str]] = {}
    for path in sorted((SRC / "simcred").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ClassDef):
                where.setdefault(node.name, []).append(
                    f"{path.relative_to(SRC).as_posix()}:{node.lineno}")
    assert not {name: places for name, places in where.items() if len(places) > 1}
