"""What the missing model(s) of a setup must satisfy, readable (paper 003, sec. V-B).

The quotient C_tc / (C_1 ⊗ … ⊗ C_k) of the test case by the composition of the given models
(:func:`~simcred.contracts.configure.missing_model_requirement`, flat composition: its size is
linear in k), projected onto the ports of the missing components (:mod:`.project`: a sufficient
requirement), simplified for printing (:mod:`.readable`), with the given models' assumptions that
the test case and the given guarantees do not ensure
(:func:`~simcred.contracts.configure.uncovered_assumptions`), each marked ``ensured`` when z3
proves it holds whenever the missing model(s) meet the requirement (at 19 given models a chain
has 8 such clauses, which used to print as 8 lines of "depends on what that model guarantees").
``simcred contracts quotient`` prints it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from simcred._json import fields_dict, json_key
from simcred.contracts import readable
from simcred.contracts.algebra import DEFAULT_TIMEOUT_MS, Contract, Status, valid
from simcred.contracts.configure import (
    missing_model_requirement,
    missing_ports,
    uncovered_assumptions,
)
from simcred.contracts.expr import Bool, conjuncts, to_text
from simcred.contracts.library import Library
from simcred.contracts.project import projection


@dataclass(frozen=True, slots=True)
class Requirement:
    """``contract``: the quotient, projected onto the missing ports when ``projected``;
    ``assumption``/``guarantee``: its readable text (the guarantee simplified where the
    assumption holds: the same contract); ``method``: how the projection was computed."""

    test_case: str
    given: dict[str, str]
    contract: Contract = field(metadata=json_key(None))
    projected: bool = field(metadata=json_key("projected_onto_ports"))
    assumption: str
    guarantee: str
    uncovered: list[dict]
    method: str

    def to_dict(self) -> dict:
        return fields_dict(self)


def requirement(library: Library, test_case: str, given: dict[str, str], *,
                timeout_ms: int = DEFAULT_TIMEOUT_MS, projection_method: str = "auto"
                ) -> Requirement:
    """The requirement on the models not in ``given`` (module docs). ``projection_method``:
    as ``method`` of :func:`~simcred.contracts.project.project` (``"qe"``: the path before
    issue 28, for comparison)."""
    quotient = missing_model_requirement(library, test_case, given)
    found = projection(quotient, missing_ports(library, given), types=library.types,
                       timeout_ms=timeout_ms, method=projection_method)
    shown = quotient if found is None else found.contract
    method = ("quotient unprojected (z3 could not eliminate the other variables)"
              if found is None else f"quotient projected onto the missing ports: "
                                    f"{found.method}")
    uncovered = _ensured(library, test_case, given, shown,
                         uncovered_assumptions(library, test_case, given,
                                               timeout_ms=timeout_ms), timeout_ms)
    return Requirement(
        test_case, dict(given), shown, found is not None,
        readable.text(readable.within(shown.assumption, types=library.types)),
        readable.text(readable.within(shown.guarantee, shown.assumption, types=library.types)),
        uncovered, method)


def _ensured(library, test_case, given, shown: Contract, uncovered: list[dict],
             timeout_ms: int) -> list[dict]:
    """Each uncovered clause with ``ensured``: z3 proves it from the test case's assumption,
    the given guarantees and the requirement's saturated guarantee (whatever missing model meets
    the requirement, the clause holds), and these premises can hold together (not vacuous)."""
    target = library.test_case(test_case)
    premises = [target.assumption, shown.saturated_guarantee,
                *(library.model_contracts[m].saturated_guarantee for m in given.values())]
    possible = valid(premises, Bool(False), types=library.types,
                     timeout_ms=timeout_ms).status is Status.FAILS
    out = []
    for item in uncovered:
        clause = next(c for c in conjuncts(library.model_contracts[item["model"]].assumption)
                      if to_text(c) == item["clause"])  # the clause itself, not its text parsed
        ensured = possible and item["kind"] != "dead end" and valid(
            premises, clause, types=library.types, timeout_ms=timeout_ms).status is Status.HOLDS
        out.append({**item, "ensured": ensured})
    return out
