"""The validation file: what a user states once to get one verdict for one test case.

YAML, read with the contracts' strict safe loader (no duplicate keys, no aliases, bounded size)
and validated with pydantic (unknown keys are errors). Every error is one line naming the file
and the key. Paths are relative to the validation file's folder. See docs/validate.md::

    name: car following, 10-25 m/s
    test_case:
      conditions: "10 <= v_leader <= 25"  # operating conditions (over the condition variables)
      tolerance: {v: 0.1}                 # largest acceptable response deviation, per feature
                                          # (or {v: {relative: 1.0}}: the reference's spread)
    reference: {path: ref.parquet}        # any format simcred reads (reader options allowed);
                                          # observed: {sensor: sensor.json} when it is a recording
    candidates:
      idm: {runs: {path: idm.parquet}, cost: 1}
    features: [gap, v, v_leader]
    inputs: [v_leader]                    # exogenous: conditioned on, not compared
    pairs: {by: run_id}                   # or groups: {by: driver}; replays pair by themselves
    conditions:                           # variables spanning the validity domain, cell edges
      v_leader: {unit: m/s, edges: [10, 15, 20, 25]}
    comparison: {bins: 3, alpha: 0.05, permutations: 199, bootstrap: 500, seed: 0}
    min_data: {runs: 8, samples: 200}     # units (runs) and samples per side and cell
    monitor: [{path: new_runs.parquet}]
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import Any

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    SerializerFunctionWrapHandler,
    ValidationError,
    ValidationInfo,
    create_model,
    field_validator,
    model_serializer,
    model_validator,
)

from simcred.compare.method import Method
from simcred.compare.observed import SensorModel
from simcred.contracts.expr import IDENTIFIER, LOGIC_WORDS
from simcred.contracts.loader import load_yaml
from simcred.errors import OptionError, SimcredError

NAME = re.compile(IDENTIFIER + "$")
RESERVED = {*LOGIC_WORDS, "deviation"}  # deviation.<feature>: the learned contracts' metrics
MAX_CELLS = 400


class ValidationFileError(SimcredError):
    """A malformed validation file; the message names the file and the key."""


class _StrictSpec(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class RunsSpec(_StrictSpec):
    """A trace set on disk: ``path`` plus reader options (:func:`simcred.io.read`)."""

    path: str = Field(min_length=1)
    options: dict[str, str | int | float | bool] = Field(default_factory=dict)


class ObservedSpec(_StrictSpec):
    """The reference is a sensor's recording of the process the candidates write as ground truth
    (docs/observed.md, the observation-model route): each candidate is pushed through ``sensor``
    before its cells are compared. ``sensor`` is a JSON file (declared, or written by ``simcred
    estimate-sensor`` with the parameter draws that carry its uncertainty) or a declared model
    inline, ``{signal: {offset, delay, noise_sd, dropout}}``."""

    sensor: Any

    @field_validator("sensor")
    @classmethod
    def _model(cls, sensor: Any) -> Any:
        if isinstance(sensor, str) and sensor:
            return sensor
        if not isinstance(sensor, dict):
            raise ValueError("a sensor model file (path) or {signal: {offset, delay, noise_sd, "
                             f"dropout}}}}, got {sensor!r}")
        try:
            SensorModel.from_dict(sensor, "declared sensor")
        except OptionError as exc:
            raise ValueError(str(exc)) from None
        return sensor


class ReferenceSpec(RunsSpec):
    """The reference's runs; ``observed``: they are a sensor's recording (:class:`ObservedSpec`).
    Without it the reference is compared as it is (and recorded as before)."""

    observed: ObservedSpec | None = None

    @model_serializer(mode="wrap")
    def _recorded(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        out = handler(self)
        if self.observed is None:
            out.pop("observed", None)
        return out


class RelativeTolerance(_StrictSpec):
    """A tolerance relative to the reference's own spread: ``relative`` times the deviation
    between random halves of the reference's units (drivers, recordings, or runs), measured over
    the test case's cells (:mod:`simcred.validate.tolerance`)."""

    relative: float = Field(gt=0, le=100, allow_inf_nan=False)


def _tolerance_value(name: Any, value: Any) -> float | RelativeTolerance:
    shape = (f"tolerance of '{name}' must be a finite number > 0 or {{relative: f}} with "
             "0 < f <= 100")
    if isinstance(value, dict):
        try:
            return RelativeTolerance.model_validate(value)
        except ValidationError:
            raise ValueError(shape) from None
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value) or value <= 0:
        raise ValueError(shape)
    return float(value)


class TestCaseSpec(_StrictSpec):
    """The test case: its operating conditions and, per response feature, the largest response
    deviation it tolerates (in the feature's unit per second, e.g. m/s² for a speed), absolute
    or relative to the reference's own spread."""

    conditions: str = Field(min_length=1)
    tolerance: dict[str, float | RelativeTolerance] = Field(min_length=1)

    @field_validator("tolerance", mode="before")
    @classmethod
    def _values(cls, tolerance: Any) -> Any:
        """Each value a number > 0 or ``{relative: f}`` with 0 < f <= 100 (one clear message,
        not one per branch of the union)."""
        if not isinstance(tolerance, dict):
            return tolerance
        out = {}
        for name, value in tolerance.items():
            out[name] = _tolerance_value(name, value)
        return out


OUT_PLACEHOLDER = "{out}"
#: Options a simulator command may not carry: ``validate`` places its output and never replaces
#: or resumes one (a validation file is a document people exchange; running it must not be able
#: to write outside ``DIR/runs/NAME/``).
WRITER_OPTIONS = ("--out", "-o", "--overwrite", "--resume")


class SimulateSpec(_StrictSpec):
    """A simcred simulator command that writes the candidate's runs: ``command`` is the argument
    list of ``simcred`` (no shell; it must start with ``simulate``), in which ``{base}`` stands
    for the validation file's folder; ``validate`` runs it with ``--out DIR/runs/NAME`` (the
    command may say ``--out {out}`` for that, nothing else). ``output`` is the trace set the
    command writes there (a relative path inside it), ``options`` go to its reader."""

    command: list[str] = Field(min_length=2, max_length=64)
    output: str = Field(min_length=1)
    options: dict[str, str | int | float | bool] = Field(default_factory=dict)

    @field_validator("command")
    @classmethod
    def _simulate(cls, command: list[str]) -> list[str]:
        if command[0] != "simulate":
            raise ValueError("a simulator command starts with 'simulate' (a simcred simulate "
                             f"subcommand), got {command[0]!r}")
        return without_placed_output(command)

    @field_validator("output")
    @classmethod
    def _inside(cls, output: str) -> str:
        parts = Path(output).parts
        if Path(output).is_absolute() or ".." in parts or OUT_PLACEHOLDER in output:
            raise ValueError(f"{output!r} must be a relative path inside the candidate's run "
                             "folder (no '..', not absolute)")
        return output


def without_placed_output(command: list[str]) -> list[str]:
    """``command`` without ``--out {out}`` (``validate`` adds the output it places); one line
    for an option that would write elsewhere, replace or resume, or a misplaced ``{out}``."""
    kept, args = [], iter(enumerate(command))
    for index, arg in args:
        option = arg.split("=", 1)[0]
        if option in ("--out", "-o") and arg == option:
            value = next(args, (None, None))[1]
            if value == OUT_PLACEHOLDER:
                continue
            raise ValueError(f"argument {index + 1}: '{arg} {value}': validate places the "
                             "output itself (DIR/runs/NAME); leave out --out")
        if option in WRITER_OPTIONS or (arg.startswith("-o") and not arg.startswith("--")):
            raise ValueError(f"argument {index + 1}: {arg!r} is not allowed: validate places, "
                             "never replaces or resumes, a simulator's output")
        if OUT_PLACEHOLDER in arg:
            raise ValueError(f"argument {index + 1}: {arg!r}: {OUT_PLACEHOLDER} stands only "
                             "for the output folder after --out")
        kept.append(arg)
    return kept


class CandidateSpec(_StrictSpec):
    """A candidate: its runs on disk, or a simulator command that makes them."""

    runs: RunsSpec | None = None
    simulate: SimulateSpec | None = None
    cost: float = Field(default=1.0, ge=0, le=1e12, allow_inf_nan=False)
    description: str = ""

    @model_validator(mode="after")
    def _one_source(self) -> CandidateSpec:
        if (self.runs is None) == (self.simulate is None):
            raise ValueError("give either runs or simulate")
        return self


class ConditionSpec(_StrictSpec):
    """One operating-condition variable: a signal of the runs, its unit and its cell edges."""

    unit: str = Field(default="dimensionless", max_length=64)
    edges: list[float] = Field(min_length=2, max_length=MAX_CELLS + 1)

    @field_validator("edges")
    @classmethod
    def _increasing(cls, edges: list[float]) -> list[float]:
        if not all(math.isfinite(e) for e in edges):
            raise ValueError("edges must be finite numbers")
        if any(b <= a for a, b in zip(edges, edges[1:], strict=False)):
            raise ValueError("edges must be strictly increasing")
        return edges


#: The fields of :class:`~simcred.compare.Method` that the ``comparison`` section does not take,
#: each with the reason (the one-line error for such a key). Every other field is a key of the
#: section (:data:`ComparisonSpec`), checked by ``Method`` itself: a new field of the method is
#: accepted here without code, unless it is added to this list.
NOT_IN_FILE = {
    "features": "the features are the file's top-level 'features'",
    "inputs": "the inputs are the file's top-level 'inputs'",
    "test": "every cell is compared by the response test",
    "pair_by": "pairs are the file's top-level 'pairs: {by: KEY}'",
    "group_by": "groups are the file's top-level 'groups: {by: KEY}'",
    "margin": "the margin of every cell is test_case.tolerance",
    "kernel": "the response comparison has no kernel option (random Fourier features of a "
              "Gaussian kernel)",
    "estimator": "the response comparison has no estimator option (its deviation is a "
                 "2-Wasserstein distance, not an MMD estimate)",
    "chain": "the response comparison has no chain option",
    "one_sided": "the response comparison counts a state seen by one side only as no evidence",
    "multiplicity": "errors are controlled over the test case's cells",
    "baseline": "the response comparison has no baseline option",
    "relevance": "feature relevance belongs to the run-level test",
    "continue_on_start_difference": "the response comparison has no start-distribution test",
    "stop_early": "stopping early belongs to the paper's per-transition permutation test",
}
#: The section's own defaults and ranges where they differ from :class:`Method`'s (type, default
#: or ``Field``); every other key has Method's default.
#: These keys come first and are always recorded (``verdict.json`` ``provenance.options``); the
#: others follow in Method's order and are recorded where the file sets them to other than
#: Method's default (so a verdict records what a file of the earlier sections recorded).
FILE_FIELDS: dict[str, tuple[Any, Any]] = {
    "bins": (int | list[int], 3),
    "alpha": (float, Field(default=0.05, gt=0, lt=1)),
    "permutations": (int, Field(default=199, ge=19, le=100_000)),
    "bootstrap": (int, Field(default=500, ge=100, le=100_000)),
    "seed": (int, Field(default=0, ge=0)),
    "resample": (float | None, Field(default=None, gt=0)),
}


class _MethodKeys(_StrictSpec):
    """Each key checked by :class:`Method` on its own (the error names the key)."""

    @field_validator("*")
    @classmethod
    def _method_checks(cls, value: Any, info: ValidationInfo) -> Any:
        try:
            Method(test="response", **{info.field_name: value})
        except OptionError as exc:
            raise ValueError(str(exc)) from None
        return value

    @model_serializer(mode="wrap")
    def _recorded(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        fields = type(self).model_fields
        return {k: v for k, v in handler(self).items()
                if k in FILE_FIELDS or getattr(self, k) != fields[k].default}


COMPARISON_DOC = """Options of the response comparison (``compare(test="response")``) in every cell:
every field of :class:`~simcred.compare.Method` except those in :data:`NOT_IN_FILE` (``bins``
per feature, the level ``alpha``, ``permutations`` of the difference test, ``bootstrap``
replicates of the deviation's bounds, ``seed``, ``resample`` (s), ``history``, ``time_bins``,
...), with the file's defaults and ranges (:data:`FILE_FIELDS`) where they differ;
:attr:`ValidationSpec.method` makes the method."""


def _comparison_spec() -> type[_StrictSpec]:
    fields = dict(FILE_FIELDS)
    fields.update((f.name, (Any, f.default)) for f in dataclasses.fields(Method)
                  if f.name not in NOT_IN_FILE and f.name not in FILE_FIELDS)
    return create_model("ComparisonSpec", __base__=_MethodKeys, __module__=__name__,
                        __doc__=COMPARISON_DOC, **fields)


ComparisonSpec = _comparison_spec()


class UnitKeySpec(_StrictSpec):
    """A per-run key: ``run_id`` or a per-run fact (``metadata["run_info"]`` key) of the runs."""

    by: str = Field(min_length=1, max_length=200)


class MinDataSpec(_StrictSpec):
    """Least data per side (reference and candidate) in a cell: units of the design (runs,
    groups or pair members) and samples; below it the cell is unknown."""

    runs: int = Field(default=8, ge=2)
    samples: int = Field(default=100, ge=2)


class SegmentSpec(_StrictSpec):
    """Runs cross cells: each run is cut into maximal segments inside one cell; segments shorter
    than ``min_length`` samples are dropped."""

    min_length: int = Field(default=10, ge=2)


class ValidationSpec(_StrictSpec):
    name: str = Field(default="validation", max_length=200)
    test_case: TestCaseSpec
    reference: ReferenceSpec
    reference_note: str = ""
    candidates: dict[str, CandidateSpec] = Field(min_length=1)
    features: list[str] = Field(min_length=1)
    inputs: list[str] = Field(default_factory=list)
    pairs: UnitKeySpec | None = None
    groups: UnitKeySpec | None = None
    conditions: dict[str, ConditionSpec] = Field(min_length=1, max_length=3)
    comparison: ComparisonSpec = Field(default_factory=ComparisonSpec)
    min_data: MinDataSpec = Field(default_factory=MinDataSpec)
    segments: SegmentSpec = Field(default_factory=SegmentSpec)
    monitor: list[RunsSpec] = Field(default_factory=list)

    @field_validator("candidates", "conditions")
    @classmethod
    def _names(cls, value: dict[str, Any]) -> dict[str, Any]:
        for name in value:
            if not NAME.match(name) or name.split(".")[0] in RESERVED:
                raise ValueError(f"'{name}' is not a usable name (letters, digits, _ and dots; "
                                 f"not {', '.join(sorted(RESERVED))})")
        return value

    @model_validator(mode="after")
    def _design(self) -> ValidationSpec:
        if self.pairs is not None and self.groups is not None:
            raise ValueError("pairs: pairs and groups cannot be combined: pair whole groups by "
                             "giving each group's runs one pair key")
        unknown = [n for n in self.inputs if n not in self.features]
        if unknown:
            raise ValueError(f"inputs: '{unknown[0]}' is not one of the features (inputs "
                             "condition the state, so they must be features)")
        if not self.response:
            raise ValueError("inputs: every feature is an input: no response is left to compare")
        for name in self.test_case.tolerance:
            if name not in self.response:
                raise ValueError(f"test_case.tolerance: '{name}' is not a response feature "
                                 f"(response features: {', '.join(self.response)})")
        return self

    @property
    def relative(self) -> dict[str, float]:
        """The features whose tolerance is relative, with their factor."""
        return {name: value.relative for name, value in self.test_case.tolerance.items()
                if isinstance(value, RelativeTolerance)}

    def with_tolerance(self, tolerance: dict[str, float]) -> ValidationSpec:
        """This spec with absolute tolerances (relative ones resolved)."""
        return self.model_copy(update={"test_case": self.test_case.model_copy(
            update={"tolerance": dict(tolerance)})})

    @property
    def method(self) -> Method:
        """The comparison of every cell: the response test on the file's features and inputs
        with the ``comparison`` section's options (:class:`~simcred.compare.Method` makes the
        checks every comparison shares; the section adds the file's own ranges and
        defaults)."""
        return Method(test="response", features=tuple(self.features), inputs=tuple(self.inputs),
                      **self.comparison.model_dump())

    @property
    def response(self) -> tuple[str, ...]:
        """The features the candidate produces (every feature that is not an input)."""
        return tuple(n for n in self.features if n not in self.inputs)

    @model_validator(mode="after")
    def _cells(self) -> ValidationSpec:
        cells = math.prod(len(c.edges) - 1 for c in self.conditions.values())
        if cells > MAX_CELLS:
            raise ValueError(f"conditions: {cells} cells (at most {MAX_CELLS})")
        return self


def read_validation(path: str | Path) -> tuple[ValidationSpec, Path]:
    """The validated spec of the file ``path`` and the folder its relative paths start from."""
    path = Path(path)
    data = load_yaml(path)
    return parse_validation(data, source=str(path)), path.resolve().parent


#: Keys of earlier versions, with what replaced them (a one-line error instead of "extra").
REMOVED = {
    ("test_case", "max_distance"): "VALID now means the response deviation is shown to be "
    "within test_case.tolerance (docs/validate.md)",
    ("acceptance",): "VALID now means shown within test_case.tolerance; there is no acceptance "
    "rule (docs/validate.md)",
}


def parse_validation(data: Any, *, source: str = "<memory>") -> ValidationSpec:
    if not isinstance(data, dict):
        raise ValidationFileError(f"{source}: a validation file is a mapping (test_case, "
                                  "reference, candidates, features, conditions, ...)")
    for path, instead in REMOVED.items():
        found = data
        for key in path:
            found = found.get(key) if isinstance(found, dict) else None
        if found is not None:
            raise ValidationFileError(f"{source}: {'.'.join(path)}: no longer an option: "
                                      f"{instead}")
    _comparison_keys(data.get("comparison"), source)
    try:
        return ValidationSpec.model_validate(data)
    except ValidationError as exc:
        error = exc.errors()[0]
        where = ".".join(str(p) for p in error["loc"])
        message = error["msg"].removeprefix("Value error, ")  # a model check names its key
        raise ValidationFileError(f"{source}: {where + ': ' if where else ''}{message}"
                                  ) from None


def _comparison_keys(section: Any, source: str) -> None:
    """One line for a key of the ``comparison`` section that is not one: a field of the method
    the file does not take (with the reason), or no field at all (with the keys it takes)."""
    if not isinstance(section, dict):
        return
    for key in section:
        if key in NOT_IN_FILE:
            raise ValidationFileError(f"{source}: comparison.{key}: not an option of the "
                                      f"validation file: {NOT_IN_FILE[key]}")
        if key not in ComparisonSpec.model_fields:
            raise ValidationFileError(
                f"{source}: comparison.{key}: unknown key (the section takes "
                f"{', '.join(ComparisonSpec.model_fields)})")
