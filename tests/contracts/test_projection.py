"""Projection of quotients at 19 given models (issue 28: `quotient` with 19 given models).

z3's classic ``qe`` gave up after its 10 s limit on a 20-component chain and the unprojected
requirement was printed; the projection now tries ``qe_rec`` first and keeps its answer only if
z3 proves it equivalent (src/simcred/contracts/project.py). Oracles: the closed form of a chain
of interval contracts computed literally from the generator's numbers (no contract reasoning),
z3 refinement of the composition, and the classic ``qe`` path on every existing example (same
printed requirement, equivalent contracts). Time is measured in benchmarks/contracts.py
(section "quotient"), never asserted here.
"""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from helpers import benchmark_module
from simcred.cli import run
from simcred.contracts import readable
from simcred.contracts.algebra import Contract, compose_all, equivalent, refines
from simcred.contracts.configure import configure, missing_model_requirement, missing_ports
from simcred.contracts.expr import children
from simcred.contracts.library import Library
from simcred.contracts.parse import parse
from simcred.contracts.project import _eliminate_by, project, projection
from simcred.contracts.requirement import requirement

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = ROOT / "examples" / "contracts" / "figure2.yaml"
UNITS = ROOT / "examples" / "contracts" / "units_and_time.yaml"
VEHICLE = ROOT / "src" / "simcred" / "data" / "contracts" / "vehicle.yaml"




chain = benchmark_module("contract_libraries").chain


def closed_form(table, choice: dict[int, int], missing: int, *, top: int = 10,
                goal: int = 9) -> tuple[str, str]:
    """The projected quotient of a chain of interval contracts, literally: model j of I_k
    assumes 0 <= x_k <= hi and guarantees 0 <= x_{k+1} <= out (their saturation: x_k in the
    domain implies the output range); the test case assumes 0 <= x_0 <= top and guarantees
    x_n <= goal; I_missing is missing.

    Assumption (∃ the other variables): x_missing ranges over the forward image of [0, top]
    through the given models before it — [0, out] while each range lies in the next domain,
    any value once one does not. Guarantee (∀ the others): the given models before the gap
    must see only inputs in their domains, and after it x_{missing+1} must lie in the next
    domain, from where every output range must lie in the next domain and the last within the
    goal; otherwise ``false``."""
    n = len(table)
    rows = [table[k][choice[k]] for k in range(n)]  # (model, hi, out, cost)
    span, inside = (0, top), True
    for k in range(missing):
        _, hi, out, _ = rows[k]
        if span is not None and span[0] >= 0 and span[1] <= hi:
            span = (0, out)
        else:
            span, inside = None, False
    assumption = "true" if span is None else f"0 <= x{missing} <= {span[1]}"
    after = missing + 1
    if after == n:
        return assumption, (f"x{n} <= {goal}" if inside else "false")
    _, hi_next, out, _ = rows[after]
    for k in range(after + 1, n):
        inside = inside and out <= rows[k][1]
        out = rows[k][2]
    inside = inside and out <= goal
    return assumption, (f"0 <= x{after} <= {hi_next}" if inside else "false")


def _same(found: Contract, assumption: str, guarantee: str) -> bool:
    return equivalent(found, Contract(parse(assumption), parse(guarantee))).holds


def test_nineteen_given_models_project_to_the_closed_form_of_the_chain(capsys):
    """The case of the issue: chain(20, 3, 1), the cheapest valid setup given except I10."""
    library, table = chain(20, 3, 1)
    setup = configure(library, "tc").setup
    given = {c: m for c, m in setup.items() if c != "I10"}
    found = requirement(library, "tc", given)
    assert found.projected
    assert found.method == ("quotient projected onto the missing ports: assumption by qe_rec, "
                            "guarantee by qe_rec")
    choice = {k: int(setup[f"I{k}"].split("_")[1]) for k in range(20)}
    assumption, guarantee = closed_form(table, choice, 10)
    assert (found.assumption, found.guarantee) == (assumption, guarantee)
    assert _same(found.contract, assumption, guarantee)
    # z3: the given models with any model meeting the requirement refine the test case, and
    # the model the configuration chose meets it
    contracts = [library.model_contracts[m] for m in given.values()]
    assert refines(compose_all([*contracts, found.contract]), library.test_case("tc")).holds
    assert refines(library.model_contracts[setup["I10"]], found.contract).holds


@pytest.mark.parametrize("seed", [4, 5, 7, 8, 9, 10, 11])  # chains with a valid setup
def test_random_chains_with_one_missing_model_project_to_the_closed_form(seed):
    """20-component chains, one component missing; the cheapest valid setup given, or with
    one model swapped at random before or after the gap (the guarantee may become false, the
    assumption true)."""
    rng = np.random.default_rng(seed)
    library, table = chain(20, 3, 100 + seed)
    setup = configure(library, "tc").setup
    choice = {k: int(setup[f"I{k}"].split("_")[1]) for k in range(20)}
    missing = int(rng.integers(1, 19))
    if seed % 3:
        k = int(rng.integers(0, missing)) if seed % 3 == 1 else int(rng.integers(missing + 1, 20))
        choice[k] = int(rng.integers(0, 3))
    given = {f"I{k}": f"M{k}_{choice[k]}" for k in range(20) if k != missing}
    quotient = missing_model_requirement(library, "tc", given)
    found = projection(quotient, missing_ports(library, given), types=library.types)
    assert found is not None and "qe_rec" in found.method
    assert _same(found.contract, *closed_form(table, choice, missing))
    assert refines(found.contract, quotient).holds  # sufficient for the quotient


def test_chain_of_11_is_the_exact_projection():
    """chain(11, 3, 1) without I5: the classic ``qe`` of z3-solver 5.4.1 answered an
    assumption that also holds at x5 = 7 (not the projection; benchmarks/contracts.py section
    "quotient"); every answer is now proven equivalent, and this one is the closed form."""
    library, table = chain(11, 3, 1)
    setup = configure(library, "tc").setup
    given = {c: m for c, m in setup.items() if c != "I5"}
    choice = {k: int(setup[f"I{k}"].split("_")[1]) for k in range(11)}
    found = requirement(library, "tc", given)
    assert (found.assumption, found.guarantee) == closed_form(table, choice, 5)
    assert _same(found.contract, *closed_form(table, choice, 5))


def _size(e) -> int:
    return 1 + sum(_size(c) for c in children(e))


def test_quotient_size_is_linear_in_the_given_models():
    library, _ = chain(20, 3, 1)
    setup = configure(library, "tc").setup
    sizes = []
    for count in (5, 10, 15):
        given = {f"I{k}": setup[f"I{k}"] for k in range(count)}
        q = missing_model_requirement(library, "tc", given)
        sizes.append(_size(q.assumption) + _size(q.guarantee))
    assert sizes[2] - sizes[1] == sizes[1] - sizes[0]  # equal increments per model


def _examples():
    cases = []
    for path in (FIGURE2, VEHICLE, UNITS):
        library = Library.read(path)
        components = library.components()
        first = {c: library.candidates(c)[0] for c in components}
        for test_case in library.spec.test_cases:
            for dropped in components:
                cases.append((path.stem, test_case,
                              {c: m for c, m in first.items() if c != dropped}))
                cases.append((path.stem, test_case, {dropped: first[dropped]}))
    return cases


@pytest.mark.parametrize(("name", "test_case", "given"), _examples(),
                         ids=lambda v: v if isinstance(v, str) else ",".join(v.values()))
def test_existing_requirements_are_unchanged(name, test_case, given):
    """Against the classic ``qe`` (the only path before): equivalent contracts, same text."""
    path = {"figure2": FIGURE2, "vehicle": VEHICLE, "units_and_time": UNITS}[name]
    library = Library.read(path)
    quotient = missing_model_requirement(library, test_case, given)
    keep = missing_ports(library, given)
    new = project(quotient, keep, types=library.types)
    old = project(quotient, keep, types=library.types, method="qe")
    assert new is not None and old is not None
    assert equivalent(new, old, types=library.types).holds

    def shown(c):
        return (readable.text(readable.within(c.assumption, types=library.types)),
                readable.text(readable.within(c.guarantee, c.assumption, types=library.types)))

    assert shown(new) == shown(old)


def test_qe_rec_is_not_applied_to_a_quantifier_free_formula():
    """On a quantifier-free goal ``qe_rec`` decides satisfiability (``x > 0`` → ``true``)."""
    import z3

    x = z3.Real("x")
    result, method = _eliminate_by(x > 0, 1_000)
    assert method == "qe" and z3.is_false(z3.simplify(z3.Xor(result, x > 0)))


def test_an_answer_z3_does_not_prove_equivalent_is_discarded(monkeypatch):
    """A wrong ``qe_rec`` result (here: ``true``) falls back to ``qe``."""
    import z3

    module = importlib.import_module("simcred.contracts.project")  # the package's name
    # `project` is the function
    real = module._apply

    def wrong(elimination, formula, timeout_ms):
        if elimination == "qe_rec":
            return z3.BoolVal(True, formula.ctx)
        return real(elimination, formula, timeout_ms)

    monkeypatch.setattr(module, "_apply", wrong)
    x, y = z3.Reals("x y")
    formula = z3.Exists([y], z3.And(y >= 0, y <= 1, x == 2 * y))
    result, method = _eliminate_by(formula, 1_000)
    assert method == "qe"
    solver = z3.Solver()
    solver.add(z3.Xor(result, z3.And(x >= 0, x <= 2)))
    assert solver.check() == z3.unsat


def test_cli_quotient_says_how_it_was_projected(capsys):
    assert run(["contracts", "quotient", str(FIGURE2), "--test-case", "C_tc", "--given",
                "I1=M1"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "assume: 0 <= q <= 50" in out and "guarantee: err <= 0.2" in out
    assert "(quotient projected onto the missing ports: assumption by qe_rec, guarantee by " \
           "qe_rec)" in out


def test_assumptions_after_the_gap_are_ensured_by_the_requirement(capsys, tmp_path):
    """19 given models: the assumptions of the models after the gap hold whenever the missing
    model meets the requirement — by the closed form: from x11 in M11's domain every output
    range lies in the next domain. With M15_0 (domain x15 <= 6 < M14_1's output bound 12) the
    requirement's guarantee is false and nothing is claimed ensured."""
    library, table = chain(20, 3, 1)
    setup = configure(library, "tc").setup
    given = {c: m for c, m in setup.items() if c != "I10"}
    rows = {m: (hi, out) for row in table for m, hi, out, _ in row}
    found = requirement(library, "tc", given)
    depends = [i for i in found.uncovered if i["kind"] == "depends"]
    assert {i["model"] for i in depends} == {given[f"I{k}"] for k in range(12, 20)}
    bound = rows[given["I11"]][1]  # closed form: the range reaching each later model
    for k in range(12, 20):
        assert bound <= rows[given[f"I{k}"]][0]
        bound = rows[given[f"I{k}"]][1]
    assert all(i["ensured"] for i in depends)
    items = " ".join(f"--given={c}={m}" for c, m in given.items()).split()
    path = _chain_file(tmp_path, 20)
    assert run(["contracts", "quotient", str(path), "--test-case", "tc", *items]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert ("the assumptions of M12_1, M13_2, M14_1, M15_2, M16_0, M17_1, M18_2, M19_1 (on x12, "
            "x13, x14, x15, x16, x17, x18, x19) hold whenever the missing model(s) meet the "
            "requirement above (proven with z3)") in out
    assert "depends on what that model guarantees" not in out

    broken = {**given, "I15": "M15_0"}
    assert rows["M15_0"][0] < rows[given["I14"]][1]
    found = requirement(library, "tc", broken)
    assert found.guarantee == "false"
    assert not any(i["ensured"] for i in found.uncovered)
    assert any(i["model"] == "M15_0" and i["clause"] == "x15 <= 6" for i in found.uncovered)


def _chain_file(folder: Path, n: int) -> Path:
    """The chain(n, 3, 1) library as a YAML file in ``folder``."""
    import yaml

    spec, _ = benchmark_module("contract_libraries").chain_spec(n, 3, 1)
    path = folder / "chain.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path
