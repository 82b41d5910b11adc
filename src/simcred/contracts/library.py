"""The contract library: variables, components, simulation models, architecture, test cases.

A YAML file (read with ``yaml.safe_load``, validated with pydantic) — see
``examples/contracts/*.yaml``::

    variables:
      ego.v: {type: real, unit: m/s}
    components:
      vehicle: {inputs: [ad.acc], outputs: [ego.v, err.pos]}
    models:
      KS: {implements: vehicle, cost: 1.7, contract: {assumption: "...", guarantee: "..."}}
    architecture: [vehicle, sensor, ad]
    test_cases:
      cutin: {assumption: "...", guarantee: "..."}
    contracts:                      # free-standing, for the algebra alone
      C1: {assumption: "...", guarantee: "..."}

A port may give its own unit (``outputs: [{ego.v: km/h}]``); every port of a variable must use
the variable's unit. Each variable is controlled by at most one output port of the architecture.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from functools import cached_property
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator

from simcred.contracts.algebra import Contract
from simcred.contracts.expr import IDENTIFIER, LOGIC_WORDS
from simcred.contracts.loader import LibraryError, load_yaml

__all__ = ["Library", "LibraryError", "LibrarySpec", "ModelSpec", "ParameterSpec", "Port"]

NAME = re.compile(rf"(?!({'|'.join(LOGIC_WORDS)})$){IDENTIFIER}")
MAX_COST = 1e12


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class VariableSpec(_Strict):
    """A variable; ``observed: false`` marks one that recorded runs do not carry (a metric such
    as the learned contracts' ``distance``): monitors check the clauses they can evaluate and
    name the guarantee clauses over it as not monitorable."""

    type: Literal["real", "int", "bool"] = "real"
    unit: str = Field("dimensionless", max_length=64)
    observed: bool = True


class ContractSpec(_Strict):
    assumption: str = "true"
    guarantee: str = "true"
    viewpoint: str = ""


class ComponentSpec(_Strict):
    inputs: list[str | dict[str, str]] = Field(default_factory=list)
    outputs: list[str | dict[str, str]] = Field(default_factory=list)


class ParameterSpec(_Strict):
    """A constant setting of a model, somewhere in ``range`` (see :mod:`.parameters`)."""

    range: tuple[float, float]
    unit: str = Field("dimensionless", max_length=64)

    @field_validator("range")
    @classmethod
    def _finite_and_ordered(cls, value):
        lo, hi = value
        if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
            raise ValueError(f"a range is [low, high] with finite low <= high, got {list(value)}")
        return value


class ModelSpec(_Strict):
    implements: str
    cost: float = Field(ge=0, le=MAX_COST, allow_inf_nan=False, strict=True)  # no 'true'
    contract: ContractSpec | list[ContractSpec] | Literal["trivial"]
    parameters: dict[str, ParameterSpec] = Field(default_factory=dict)
    description: str = ""

    @field_validator("contract")
    @classmethod
    def _some_viewpoint(cls, value):
        if isinstance(value, list) and not value:
            raise ValueError("a list of viewpoints needs at least one contract (or write "
                             "'trivial' for none)")
        return value

    @property
    def viewpoints(self) -> list[ContractSpec]:
        """The model's contracts (several viewpoints are combined by conjunction)."""
        if self.contract == "trivial":
            return [ContractSpec()]
        return self.contract if isinstance(self.contract, list) else [self.contract]


class LibrarySpec(_Strict):
    variables: dict[str, VariableSpec] = Field(default_factory=dict)
    components: dict[str, ComponentSpec] = Field(default_factory=dict)
    models: dict[str, ModelSpec] = Field(default_factory=dict)
    architecture: list[str] = Field(default_factory=list)
    test_cases: dict[str, ContractSpec] = Field(default_factory=dict)
    contracts: dict[str, ContractSpec] = Field(default_factory=dict)

    @field_validator("variables", mode="before")
    @classmethod
    def _short_variables(cls, value):
        """``x: real`` is short for ``x: {type: real}``."""
        if isinstance(value, dict):
            return {k: {"type": v} if isinstance(v, str) else v for k, v in value.items()}
        return value


@dataclass(frozen=True, slots=True)
class Port:
    component: str
    variable: str
    unit: str
    direction: Literal["input", "output"]


@dataclass(frozen=True)
class Library:
    """A validated library; contracts are parsed against the declared variables, except those
    a program built as ASTs and hands over in ``built`` (keyed by where the library names them,
    ``models.<name>.contract``): they are taken as they are (their text in ``spec`` is what a
    file of the library says; a program that builds both keeps them the same)."""

    spec: LibrarySpec
    source: str = "<memory>"
    built: Mapping[str, Contract] = field(default_factory=dict, compare=False, repr=False)

    @classmethod
    def read(cls, path: str | Path) -> Library:
        """Read and validate a library file (see :mod:`simcred.contracts.loader` for limits)."""
        return cls.from_dict(load_yaml(Path(path)), source=str(path))

    @classmethod
    def from_dict(cls, data, *, source: str = "<memory>",
                  built: Mapping[str, Contract] | None = None) -> Library:
        if not isinstance(data, dict):
            raise LibraryError(f"{source}: a library is a mapping with variables, components, "
                               "models, architecture, test_cases, contracts")
        try:
            spec = LibrarySpec.model_validate(data)
        except ValidationError as exc:
            error = exc.errors()[0]
            where = ".".join(str(p) for p in error["loc"] if not _is_type_tag(p))
            message = error["msg"].removeprefix("Value error, ")
            raise LibraryError(f"{source}: {where}: {message}") from None
        library = cls(spec, source, dict(built or {}))
        library.validate()
        return library

    # -- names -------------------------------------------------------------------------------

    @property
    def types(self) -> dict[str, str]:
        return {name: v.type for name, v in self.spec.variables.items()}

    @property
    def unobserved(self) -> frozenset[str]:
        """Variables no recorded run carries (``observed: false``)."""
        return frozenset(n for n, v in self.spec.variables.items() if not v.observed)

    @property
    def units(self) -> dict[str, str]:
        return {name: v.unit for name, v in self.spec.variables.items()}

    def _contract(self, spec: ContractSpec, where: str, name: str,
                  parameters: dict[str, ParameterSpec] | None = None) -> Contract:
        if where in self.built:
            return self.built[where]
        parameters = parameters or {}
        declared = {**self.spec.variables, **parameters}
        units = {**self.units, **{p: v.unit for p, v in parameters.items()}}
        return Contract.from_strings(spec.assumption, spec.guarantee, name=name,
                                     declared=declared, where=f"{self.source}: {where}",
                                     types=self.types, units=units)

    @cached_property
    def model_contracts(self) -> dict[str, Contract]:
        """Each model's contract: the conjunction of its viewpoints (paper 003 sec. III-A,
        C_tot; Benveniste et al. 2008, multiple viewpoints)."""
        from simcred.contracts.parameters import eliminate

        out = {}
        for n, m in self.spec.models.items():
            clash = sorted(set(m.parameters) & set(self.spec.variables))
            if clash:
                raise LibraryError(f"{self.source}: models.{n}.parameters.{clash[0]}: also a "
                                   "variable (a parameter needs its own name)")
            views = m.viewpoints
            parts = [self._contract(v, f"models.{n}.contract" + (f"[{i}]" if len(views) > 1
                                                                 else ""), n, m.parameters)
                     for i, v in enumerate(views)]
            whole = parts[0]
            for part in parts[1:]:
                whole = whole.conjoin(part)
            ranges = {p: (Fraction(repr(v.range[0])), Fraction(repr(v.range[1])))
                      for p, v in m.parameters.items()}  # the decimals as written
            whole = eliminate(whole, ranges, types=self.types,
                              where=f"{self.source}: models.{n}.parameters")
            out[n] = Contract(whole.assumption, whole.guarantee, n)
        return out

    @cached_property
    def test_case_contracts(self) -> dict[str, Contract]:
        return {n: self._contract(t, f"test_cases.{n}", n)
                for n, t in self.spec.test_cases.items()}

    @cached_property
    def named_contracts(self) -> dict[str, Contract]:
        return {n: self._contract(c, f"contracts.{n}", n) for n, c in self.spec.contracts.items()}

    def contract(self, name: str) -> Contract:
        """A free-standing contract, a model's contract or a test case's, by name."""
        for table in (self.named_contracts, self.model_contracts, self.test_case_contracts):
            if name in table:
                return table[name]
        known = sorted({*self.named_contracts, *self.model_contracts, *self.test_case_contracts})
        raise LibraryError(f"{self.source}: no contract, model or test case named '{name}' "
                           f"(known: {', '.join(known)})")

    def test_case(self, name: str) -> Contract:
        if name not in self.test_case_contracts:
            raise LibraryError(f"{self.source}: no test case named '{name}' (known: "
                               f"{', '.join(sorted(self.test_case_contracts))})")
        return self.test_case_contracts[name]

    def candidates(self, component: str) -> list[str]:
        """The models implementing ``component``, cheapest first."""
        return sorted((n for n, m in self.spec.models.items() if m.implements == component),
                      key=lambda n: (self.spec.models[n].cost, n))

    def ports(self, component: str) -> list[Port]:
        spec = self.spec.components[component]
        return [self._port(component, entry, direction)
                for direction, entries in (("input", spec.inputs), ("output", spec.outputs))
                for entry in entries]

    def _port(self, component: str, entry, direction) -> Port:
        where = f"{self.source}: components.{component}.{direction}s"
        if isinstance(entry, dict) and len(entry) != 1:
            raise LibraryError(f"{where}: a port is a name or one 'name: unit' pair, got {entry}")
        variable, unit = (entry, None) if isinstance(entry, str) else next(iter(entry.items()))
        if variable not in self.spec.variables:
            raise LibraryError(f"{where}: undeclared variable '{variable}'")
        return Port(component, variable, unit or self.spec.variables[variable].unit, direction)

    def controlled(self, component: str) -> set[str]:
        return {p.variable for p in self.ports(component) if p.direction == "output"}

    def uncontrolled(self, component: str) -> set[str]:
        return {p.variable for p in self.ports(component) if p.direction == "input"}

    def components(self) -> list[str]:
        """The components of the architecture (all components if none is given)."""
        return self.spec.architecture or list(self.spec.components)

    def environment(self) -> set[str]:
        """Ports of the architecture that no component drives: what a test case may assume."""
        ports = {p.variable for c in self.components() for p in self.ports(c)}
        return ports - set().union(*(self.controlled(c) for c in self.components()))

    # -- validation ---------------------------------------------------------------------------

    def validate(self) -> None:
        """Names, units, composability, port scope and non-vacuity (see :mod:`.wellformed`)."""
        from simcred.contracts.wellformed import check_library

        check_library(self)


def _is_type_tag(part) -> bool:
    """pydantic's union branch names in error locations (``function-after[...]``, ``str``)."""
    return isinstance(part, str) and (part in ("str", "list[...]", "dict[str,str]")
                                      or "[" in part or part.startswith("literal"))
