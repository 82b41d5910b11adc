"""What the missing model(s) of a setup must satisfy, readable (seed 003, sec. V-B).

The quotient C_tc / (C_1 ⊗ … ⊗ C_k) of the test case by the composition of the given models
(:func:`~simcred.contracts.configure.missing_model_requirement`, flat composition: its size is
linear in k), projected onto the ports of the missing components (:mod:`.project`: a sufficient
requirement), simplified for printing (:mod:`.readable`), with the given models' assumptions that
the test case and the given guarantees do not ensure
(:func:`~simcred.contracts.configure.uncovered_assumptions`). ``simcred contracts quotient``
prints it.
"""

from __future__ import annotations

from dataclasses import dataclass

from simcred.contracts import readable
from simcred.contracts.algebra import DEFAULT_TIMEOUT_MS, Contract
from simcred.contracts.configure import (
    missing_model_requirement,
    missing_ports,
    uncovered_assumptions,
)
from simcred.contracts.library import Library
from simcred.contracts.project import projection


@dataclass(frozen=True, slots=True)
class Requirement:
    """``contract``: the quotient, projected onto the missing ports when ``projected``;
    ``assumption``/``guarantee``: its readable text (the guarantee simplified where the
    assumption holds: the same contract); ``method``: how the projection was computed."""

    test_case: str
    given: dict[str, str]
    contract: Contract
    projected: bool
    assumption: str
    guarantee: str
    uncovered: list[dict]
    method: str

    def to_dict(self) -> dict:
        return {"test_case": self.test_case, "given": self.given,
                "projected_onto_ports": self.projected, "assumption": self.assumption,
                "guarantee": self.guarantee, "uncovered": self.uncovered,
                "method": self.method}


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
    return Requirement(
        test_case, dict(given), shown, found is not None,
        readable.text(readable.within(shown.assumption, types=library.types)),
        readable.text(readable.within(shown.guarantee, shown.assumption, types=library.types)),
        uncovered_assumptions(library, test_case, given, timeout_ms=timeout_ms), method)
