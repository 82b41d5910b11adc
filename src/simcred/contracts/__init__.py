"""Assume-guarantee contracts of simulation models (Braun et al., paper 003).

The public face: the assertion language (:func:`parse`), contracts and their algebra
(:class:`Contract`, :func:`refines`, ...), libraries (:class:`Library`), configuration of the
cheapest sufficiently valid setup (:func:`configure`), quotients and their readable form, and
monitors of recorded runs (:func:`monitor`). See docs/contracts.md.
"""

from simcred.contracts.algebra import (
    Contract,
    Status,
    Verdict,
    compatible,
    compose_all,
    consistent,
    equivalent,
    receptive,
    refines,
    valid,
)
from simcred.contracts.configure import (
    Configuration,
    configure,
    missing_model_requirement,
    missing_ports,
    setup_contract,
    setup_refines,
    uncovered_assumptions,
)
from simcred.contracts.evaluate import evaluate, margin
from simcred.contracts.expr import ExpressionError, to_text
from simcred.contracts.library import Library, LibraryError
from simcred.contracts.monitor import MonitorReport, Violation, monitor
from simcred.contracts.parse import parse
from simcred.contracts.project import project
from simcred.contracts.readable import text as readable_text
from simcred.contracts.requirement import Requirement, requirement
from simcred.contracts.temporal import Timeline

__all__ = [
    "Configuration",
    "Contract",
    "ExpressionError",
    "Library",
    "LibraryError",
    "MonitorReport",
    "Requirement",
    "Status",
    "Timeline",
    "Verdict",
    "Violation",
    "compatible",
    "compose_all",
    "configure",
    "consistent",
    "equivalent",
    "evaluate",
    "margin",
    "missing_model_requirement",
    "missing_ports",
    "monitor",
    "parse",
    "project",
    "readable_text",
    "receptive",
    "refines",
    "requirement",
    "setup_contract",
    "setup_refines",
    "to_text",
    "uncovered_assumptions",
    "valid",
]
