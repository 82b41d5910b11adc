"""Well-formedness of a library: what must hold before any contract may certify anything.

* names: variables are valid identifiers; models, test cases and free contracts have distinct
  names; components, architecture and models refer to what exists;
* units and composability (paper 003 sec. III-D4): every port of a variable uses its unit, every
  variable is driven by at most one output, no component both reads and drives a variable;
* port scope (paper 003 sec. III-D1: "the contract C = (A, G) is modeled over the ports P_M"):
  a model's assumption constrains only its component's inputs, its guarantee only the
  component's inputs and outputs; a test case speaks only about the architecture's ports, and
  its assumption only about what the architecture does not drive (the environment);
* no silent vacuity: an assumption that no point satisfies (a model's or a test case's) would
  make every check pass, so it is an error;
* division only by non-zero constants: ``v / (q - q)`` or ``v / (2 - 2)`` has no value where the
  divisor is zero, and z3 and numpy would each give it a different one;
* no variable named ``t``: recorded runs carry their time stamps in the column ``t``, so a
  monitor would silently read the time as the variable.

Every violation is a one-line :class:`LibraryError` naming the file, the entry and the variable.
"""

from __future__ import annotations

from collections.abc import Iterable

from simcred.contracts.algebra import Status, valid
from simcred.contracts.expr import (
    Arith,
    Bool,
    Expr,
    children,
    conjuncts,
    is_temporal,
    to_text,
    variables,
)
from simcred.contracts.loader import LibraryError
from simcred.contracts.units import same_unit, unit
from simcred.traces import TIME

SATISFIABILITY_TIMEOUT_MS = 2_000


def check_library(library) -> None:
    """Raise a one-line :class:`LibraryError` on the first violation (module docs)."""
    _check_names(library)
    library.model_contracts, library.test_case_contracts, library.named_contracts  # noqa: B018
    _check_ports(library)
    _check_scope(library)
    _check_divisions(library)
    _check_not_vacuous(library)


def _check_names(library) -> None:
    from simcred.contracts.library import NAME

    spec, source = library.spec, library.source
    for name, variable in spec.variables.items():
        if name == TIME:
            raise LibraryError(f"{source}: variables.{name}: '{TIME}' is the time column of "
                               "recorded runs (a monitor would read the time stamps as this "
                               "variable); rename it")
        if not NAME.fullmatch(name):
            raise LibraryError(f"{source}: variables.{name}: not a valid variable name (letters, "
                               "digits, '_' and dots; not a keyword)")
        unit(variable.unit, where=f"{source}: variables.{name}.unit")
    for name, model in spec.models.items():
        if model.implements not in spec.components:
            raise LibraryError(f"{source}: models.{name}.implements: unknown component "
                               f"'{model.implements}'")
    for name in spec.architecture:
        if name not in spec.components:
            raise LibraryError(f"{source}: architecture: unknown component '{name}'")
        if spec.architecture.count(name) > 1:
            raise LibraryError(f"{source}: architecture: component '{name}' listed twice")
    tables = {"models": spec.models, "test_cases": spec.test_cases, "contracts": spec.contracts}
    seen: dict[str, str] = {}
    for table, entries in tables.items():
        for name in entries:
            if name in seen:
                raise LibraryError(f"{source}: {table}.{name}: the name is also used in "
                                   f"{seen[name]} (names must be unique)")
            seen[name] = table


def _components(library) -> list[str]:
    return library.spec.architecture or list(library.spec.components)


def _check_ports(library) -> None:
    source = library.source
    drivers: dict[str, str] = {}
    for component in _components(library):
        ports = library.ports(component)
        both = library.controlled(component) & library.uncontrolled(component)
        if both:
            raise LibraryError(f"{source}: components.{component}: '{sorted(both)[0]}' is both "
                               "an input and an output")
        for port in ports:
            declared = library.spec.variables[port.variable].unit
            if not same_unit(port.unit, declared):
                raise LibraryError(
                    f"{source}: components.{component}: port '{port.variable}' in "
                    f"{port.unit} but the variable is in {declared} (unit mismatch)")
            if port.direction == "output":
                if port.variable in drivers:
                    raise LibraryError(
                        f"{source}: variable '{port.variable}' is driven by two outputs "
                        f"({drivers[port.variable]} and {component})")
                drivers[port.variable] = component


def _outside(expr: Expr, allowed: set[str]) -> tuple[str, str] | None:
    """(clause, variable) of the first clause of ``expr`` that mentions a variable outside
    ``allowed``, or None."""
    for clause in conjuncts(expr):
        extra = sorted(variables(clause) - allowed)
        if extra:
            return to_text(clause), extra[0]
    return None


def _check_scope(library) -> None:
    source = library.source
    for name, contract in library.model_contracts.items():
        component = library.spec.models[name].implements
        inputs, outputs = library.uncontrolled(component), library.controlled(component)
        for part, expr, allowed, what in (
                ("assumption", contract.assumption, inputs, "inputs"),
                ("guarantee", contract.guarantee, inputs | outputs, "inputs and outputs")):
            found = _outside(expr, allowed)
            if found:
                clause, variable = found
                raise LibraryError(
                    f"{source}: models.{name}.contract.{part}: '{variable}' is not a port of "
                    f"component '{component}' (clause '{clause}'; a model's {part} may only "
                    f"constrain its component's {what}: {', '.join(sorted(allowed)) or 'none'})")
    components = _components(library)
    driven = set().union(*(library.controlled(c) for c in components)) if components else set()
    ports = set().union(*(library.controlled(c) | library.uncontrolled(c)
                          for c in components)) if components else set()
    for name, contract in library.test_case_contracts.items():
        for part, expr, allowed, what in (
                ("assumption", contract.assumption, ports - driven,
                 "the environment (ports no component drives)"),
                ("guarantee", contract.guarantee, ports, "the architecture's ports")):
            found = _outside(expr, allowed)
            if found:
                clause, variable = found
                raise LibraryError(f"{source}: test_cases.{name}.{part}: '{variable}' is not "
                                   f"allowed here (clause '{clause}'; a test case's {part} "
                                   f"speaks only about {what})")


def _divisions(expr: Expr) -> Iterable[Arith]:
    stack = [expr]
    while stack:
        e = stack.pop()
        if isinstance(e, Arith) and e.op == "/":
            yield e
        stack.extend(children(e))


def _all_contracts(library):
    yield from ((f"models.{n}.contract", c) for n, c in library.model_contracts.items())
    yield from ((f"test_cases.{n}", c) for n, c in library.test_case_contracts.items())
    yield from ((f"contracts.{n}", c) for n, c in library.named_contracts.items())


def _check_divisions(library) -> None:
    for where, contract in _all_contracts(library):
        for part in ("assumption", "guarantee"):
            for division in _divisions(getattr(contract, part)):
                if variables(division.args[1]):
                    raise LibraryError(
                        f"{library.source}: {where}.{part}: division by "
                        f"'{to_text(division.args[1])}', which has variables (it may be zero; "
                        "multiply out instead, e.g. 'd >= 2 s * v' for 'd / v >= 2 s')")
                if _is_zero(division.args[1]):
                    raise LibraryError(f"{library.source}: {where}.{part}: division by zero "
                                       f"('{to_text(division.args[1])}' is 0)")


def _is_zero(constant: Expr) -> bool:
    """Is a constant term exactly zero? (z3 folds it in exact rationals.)"""
    import z3

    from simcred.contracts.smt import to_z3

    value = z3.simplify(to_z3(constant, {}))
    return z3.is_rational_value(value) and value.numerator_as_long() == 0


def _check_not_vacuous(library) -> None:
    from simcred.contracts.intervals import satisfiable

    entries = [(f"models.{n}.contract.assumption", c.assumption)
               for n, c in library.model_contracts.items()]
    entries += [(f"test_cases.{n}.assumption", c.assumption)
                for n, c in library.test_case_contracts.items()]
    for where, assumption in entries:
        if assumption == Bool(True) or is_temporal(assumption):
            continue  # temporal clauses: no static decision (monitors check them on runs)
        decided = satisfiable(assumption, library.types)
        if decided is None:
            verdict = valid([assumption], Bool(False), types=library.types,
                            timeout_ms=SATISFIABILITY_TIMEOUT_MS)
            decided = None if verdict.status is Status.UNKNOWN else not verdict.holds
        if decided is False:
            raise LibraryError(f"{library.source}: {where}: '{to_text(assumption)[:120]}' is "
                               "unsatisfiable, so the contract would hold vacuously")
