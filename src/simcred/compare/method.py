"""The comparison method: every option of a comparison except the data, validated once.

:class:`Method` is what :func:`~simcred.compare.compare`, :func:`~simcred.compare.matrix`, the
out-of-core path, ``validate``, ``study`` and the CLI share (as scipy passes
``method=PermutationMethod(...)``). Each field is declared once, here: its default, its check
(in ``__post_init__``) and, in the field's metadata, its command-line help; the CLI generates
one option per field for ``simcred compare`` and ``simcred matrix``
(:mod:`simcred.cli._method`). Checks that need the data (the features exist, enough runs, equal
sample periods) are made against the sets' facts by
:func:`~simcred.compare.process.comparison_options`, which also resolves what depends on the test
and the data into the :class:`~simcred.compare.result.ComparisonOptions` a result records.

>>> m = Method(test="bound", bins=5, alpha=0.05)
>>> m.test, m.bins, m.alpha
(<Test.BOUND: 'bound'>, 5, 0.05)
>>> Method(chain="median")
Traceback (most recent call last):
...
simcred.errors.OptionError: chain must be one of sum, max; got 'median'
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simcred.compare.encoding import check_history, check_time_bins
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, Test
from simcred.compare.resample import check_resample
from simcred.compare.runs import ChainStatistic, Multiplicity, OneSided
from simcred.errors import OptionError
from simcred.seeds import resolve_seed

#: The commands that take every option unless a field names fewer (metadata ``commands``).
COMMANDS = ("compare", "matrix")


def option(default: Any = None, *, help: str, tests: tuple[str, ...] | None = None,
           commands: tuple[str, ...] = COMMANDS, flags: tuple[str, ...] = (),
           cli_default: Any = dataclasses.MISSING) -> Any:
    """A field of :class:`Method` with what the command line needs to offer it: ``help``,
    the ``commands`` that offer it, the option's ``flags`` (default ``--field-name``), its
    default there when it differs (``cli_default``) and the ``tests`` it applies to (the CLI
    passes it only to those)."""
    return field(default=default, metadata={"help": help, "tests": tests, "commands": commands,
                                            "flags": flags, "cli_default": cli_default})


@dataclass(frozen=True, slots=True)
class Method:
    """How to compare two sets of runs (Neurohr et al. 2023 [1], sec. V-A, and its extensions).

    Every field is checked on construction (one line, :class:`~simcred.errors.OptionError`);
    a field that does not apply to the chosen ``test`` is kept and ignored (the result's
    ``options`` record what was used). docs/comparison.md describes the tests.

    Parameters
    ----------
    features : sequence of str or comma-separated str, default: all signals
        The signals that span the state space. Default: every signal, which requires both sets to
        have the same signal names.
    bins : int or sequence of int, default: 10
        Equal-frequency bins per feature (before duplicate edges are removed), at least 2.
    kernel : {"gaussian", "laplace", "linear"}, default: "gaussian"
        [1] eqs. (3)-(5); Gaussian and Laplace use the median heuristic for σ.
    estimator : {"biased", "unbiased"}, default: "biased"
        MMD_b (the paper's, reported not squared) or MMD²_u.
    test : {"runs", "response", "bound", "permutation"}, default: "runs"
        ``runs``: run-level permutation test (whole runs reassigned; valid under any dependence
        within runs) with a chain-level verdict; ``response``: the conditional test of the
        response law given the state (docs/comparison.md: run lengths, visit frequencies,
        start states and declared inputs are not part of its H0; paired and grouped designs;
        effect sizes with intervals; equivalence); ``bound``: the paper's Gretton-type bound;
        ``permutation``: the paper's per-transition permutation test. The last two treat
        transitions as independent samples.
    alpha : float, default: 0.01
        Level of every single test (and of the chain verdict), in (0, 1).
    permutations : int, default: 999
        Resamples of the permutation tests.
    seed : int, Generator or None
        Seed of the permutation tests. None draws fresh entropy, which is stored in the result.
    multiplicity : {"fwer", "fdr", "none"}, default: "fwer" for ``runs``, else "none"
        Control of the per-state verdicts: max-T family-wise, Benjamini–Hochberg, or none (the
        paper's). Only ``runs`` supports "fwer" and "fdr".
    chain : {"sum", "max"}, default: "sum"
        Chain statistic of the run-level test: sum or maximum of standardised state statistics.
    one_sided : {"evidence", "neutral"}, default: "evidence"
        Run-level test: a state without transitions on one side counts as the largest possible
        difference, or as no evidence.
    history : int, default: 1
        States are the last ``history`` binned feature vectors (1 = the paper's chain).
    time_bins : int or None
        Time since run start, binned into ``time_bins`` equal-frequency windows, becomes part
        of the state (time-inhomogeneous chain). At least 2; None = time-homogeneous.
    resample : float or None
        Resample every run to this period (s) by linear interpolation. Without it, sets with
        different sample periods are refused.
    baseline : int, default: 0
        Run-level test: number of random half-splits of set A compared against each other, the
        distance's same-model baseline.
    bootstrap : int, default: 0 (``response``: 500)
        Run-level test: bootstrap replicates (runs resampled within each set) for a re-test
        spread of the distance. Response test: cluster-bootstrap replicates of the effect
        intervals (units resampled within each set, or whole pairs).
    relevance : bool, default: False
        Run-level test: chain statistics on each feature alone and with each feature left out.
    continue_on_start_difference : bool, default: False
        Bound/permutation tests: test the transitions even when the start distributions differ.
    stop_early : bool, default: True
        Permutation test: stop drawing once rejection is impossible (Besag & Clifford 1991).
        Verdicts are those of the full test; p-values above ``alpha`` become sequential
        estimates. False always draws all ``permutations``.
    inputs : sequence of str or comma-separated str
        Response test: features the model does not control (a recorded leader's speed):
        they condition the state but their own evolution is not compared.
    pair_by : str, optional
        Response test: ``"run_id"``, a per-run fact (``metadata["run_info"]``) or a signal
        constant within each run that pairs run *i* of B with the run of A whose scenario it
        replays; the null swaps within pairs.
    group_by : str, optional
        Response test: a per-run fact (driver, recording, parent run of a segment) or a signal
        constant within each run whose runs form one exchangeable unit; whole groups are
        permuted and resampled.
    margin : float or mapping, optional
        Response test: equivalence margin per response feature (its unit per second), or one
        for all; the result says whether equivalence within the margin is shown.

    References
    ----------
    [1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of
        ADSs, IEEE Access, 2023.
    """

    features: tuple[str, ...] | None = option(
        help="Comma-separated signals spanning the state space (default: all signals, which "
             "both sets must share).", flags=("--features", "-f"))
    bins: int | tuple[int, ...] = option(
        10, help="Equal-frequency bins per feature (≥ 2), or one per feature: 10,8.")
    kernel: Kernel = option(Kernel.GAUSSIAN, help="MMD kernel.")
    estimator: Estimator = option(Estimator.BIASED, help="MMD estimator: the paper's biased "
                                                        "MMD_b or the unbiased MMD²_u.")
    test: Test = option(
        Test.RUNS,
        help="runs: run-level permutation test with a chain verdict (whole runs reassigned, valid "
             "when transitions within a run are dependent); response: the law of the response "
             "given the state (run lengths, visit frequencies and declared inputs are not part "
             "of it; paired/grouped designs, effect with interval, equivalence); bound / "
             "permutation: the paper's per-transition tests.")
    alpha: float = option(0.01, help="Level of each test, in (0, 1).")
    permutations: int = option(999, help="Resamples of the permutation test.")
    seed: int | np.random.Generator | None = option(
        help="Seed (default: fresh entropy, stored in the result).")
    multiplicity: Multiplicity | None = option(
        help="Per-state verdicts of the runs test: family-wise (max-T), FDR (Benjamini-Hochberg) "
             "or uncorrected. Default: fwer for --test runs, none otherwise.")
    chain: ChainStatistic = option(
        ChainStatistic.SUM, help="Chain statistic of the runs test: sum or max of standardised "
                                 "state statistics.")
    one_sided: OneSided = option(
        OneSided.EVIDENCE, help="Runs test: a state reached by one set only counts as evidence "
                                "of a difference, or as neutral.")
    history: int = option(1, help="States are the last K binned feature vectors (1 = the "
                                  "paper's first-order chain).")
    time_bins: int | None = option(
        help="Split time since run start into N equal-frequency windows that become part of "
             "the state (N >= 2).")
    resample: float | None = option(
        help="Resample every run to this period in seconds (linear interpolation); needed when "
             "the sets have different sample periods.")
    baseline: int = option(
        0, help="Runs test: random half-splits of A compared with each other (the distance's "
                "same-model baseline); 0 = none.", tests=("runs",), commands=("compare",),
        cli_default=10)
    bootstrap: int = option(
        0, help="Runs test: bootstrap replicates for the distance's 95 % re-test spread "
                "(biased upward, not a confidence interval); 0 = none.",
        tests=("runs", "response"), commands=("compare",))
    relevance: bool = option(
        False, help="Runs test: chain test per feature alone and per feature left out.",
        tests=("runs",), commands=("compare",))
    inputs: tuple[str, ...] = option(
        (), help="Response test: comma-separated features the model does not control (a "
                 "recorded leader's speed); they condition the state and are not compared.",
        tests=("response",), commands=("compare",))
    pair_by: str | None = option(
        help="Response test: run_id, a per-run fact or a signal constant within each run, "
             "pairing each run of B with the run of A it replays (the null swaps within "
             "pairs).", tests=("response",),
        commands=("compare",))
    group_by: str | None = option(
        help="Response test: a per-run fact (driver, recording, parent run) or a signal "
             "constant within each run, whose runs form one unit, permuted and resampled "
             "whole.", tests=("response",),
        commands=("compare",))
    margin: float | tuple[tuple[str, float], ...] | None = option(
        help="Response test: equivalence margin of the response deviation, per second: one "
             "number for every response feature, or FEATURE=NUMBER,...", tests=("response",),
        commands=("compare",))
    continue_on_start_difference: bool = option(
        False, help="Test transitions even if the start distributions differ.",
        flags=("--continue-on-start-difference",))
    stop_early: bool = option(
        True, help="Permutation test: stop once rejection is impossible (same verdicts; "
                   "p-values above alpha are then sequential estimates), or always draw all "
                   "permutations.", flags=("--stop-early/--all-permutations",))

    def __post_init__(self) -> None:
        """The checks that need no data, in the order :func:`compare` has always made them."""
        def _set(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        _set("features", None if self.features is None else feature_names(self.features))
        _set("estimator", _choice(Estimator, self.estimator, "estimator"))
        _set("test", _choice(Test, self.test, "test"))
        _set("inputs", _names(self.inputs, "inputs"))
        self._check_response()
        _set("multiplicity", _choice(Multiplicity, self.multiplicity, "multiplicity")
             if self.multiplicity else None)
        self._check_multiplicity()
        _set("resample", check_resample(self.resample))
        _set("kernel", _choice(Kernel, self.kernel, "kernel"))
        _set("alpha", check_alpha(self.alpha))
        if self.test is not Test.BOUND:
            _set("permutations", check_permutations(self.permutations))
        if self.seed is not None and not isinstance(self.seed, np.random.Generator):
            _set("seed", resolve_seed(self.seed))
        _set("chain", _choice(ChainStatistic, self.chain, "chain"))
        _set("one_sided", _choice(OneSided, self.one_sided, "one-sided"))
        _set("history", check_history(self.history))
        _set("time_bins", check_time_bins(self.time_bins))
        self._check_counts()
        _set("bins", self.bins if isinstance(self.bins, numbers.Integral)
             else tuple(self.bins))
        for name, text in (("pair_by", "pair-by"), ("group_by", "group-by")):
            _set(name, _key(getattr(self, name), text))
        if isinstance(self.margin, Mapping):
            _set("margin", tuple(self.margin.items()))
        for name in ("relevance", "continue_on_start_difference", "stop_early"):
            _set(name, bool(getattr(self, name)))

    @classmethod
    def of(cls, method: Method | None = None, **options: Any) -> Method:
        """``method`` (default: the defaults) with ``options`` replaced: how :func:`compare`
        and :func:`matrix` take either a method or the options as keywords."""
        if method is None:
            return cls(**options)
        if not isinstance(method, Method):
            raise OptionError(f"method must be a simcred.compare.Method, got {method!r}")
        return dataclasses.replace(method, **options) if options else method

    @property
    def multiplicity_used(self) -> Multiplicity:
        """The per-state control used: the given one, else fwer (runs, response) or none."""
        if self.multiplicity is not None:
            return self.multiplicity
        return Multiplicity.FWER if self.test in (Test.RUNS, Test.RESPONSE) \
            else Multiplicity.NONE

    @property
    def margins(self) -> float | dict[str, float] | None:
        """The margin as :func:`~simcred.compare.effect.check_margins` takes it."""
        return dict(self.margin) if isinstance(self.margin, tuple) else self.margin

    def _check_response(self) -> None:
        response = self.test is Test.RESPONSE
        if not response and (self.inputs or self.pair_by or self.group_by
                             or self.margin is not None):
            raise OptionError("inputs, pair-by, group-by and margin belong to the response test "
                              "(--test response)")
        if response and self.baseline:
            raise OptionError("the response test has no random-halves baseline (it cannot see "
                              "heterogeneity of the reference); use --baseline 0")

    def _check_multiplicity(self) -> None:
        multiplicity = self.multiplicity_used
        if self.test is Test.RESPONSE and multiplicity is not Multiplicity.FWER:
            raise OptionError("the response test's per-state verdicts are family-wise (max-T, "
                              "after the chain verdict); multiplicity must be fwer")
        if self.test in (Test.BOUND, Test.PERMUTATION) and multiplicity is not Multiplicity.NONE:
            raise OptionError(f"multiplicity {multiplicity.value} needs the run-level test "
                              "(--test runs); the paper's tests are per state only")

    def _check_counts(self) -> None:
        if self.test is Test.RUNS:
            object.__setattr__(self, "baseline", check_count(self.baseline, "baseline"))
        if self.test in (Test.RUNS, Test.RESPONSE):
            object.__setattr__(self, "bootstrap", check_count(self.bootstrap, "bootstrap"))


def feature_names(features: Sequence[str] | str) -> tuple[str, ...]:
    """Names from a sequence or a comma-separated text: non-empty, distinct."""
    names = tuple(f.strip() for f in features.split(",")) if isinstance(features, str) \
        else tuple(features)
    if not names or any(not n for n in names):
        raise OptionError(f"features must be non-empty signal names, got {features!r}")
    if len(set(names)) != len(names):
        raise OptionError(f"features repeat a name: {list(names)}")
    return names


def _choice(enum: type, value: str, name: str):
    try:
        return enum(value)
    except ValueError:
        choices = ", ".join(e.value for e in enum)
        raise OptionError(f"{name} must be one of {choices}; got {value!r}") from None


def _names(value: Sequence[str] | str, option: str) -> tuple[str, ...]:
    names = tuple(v.strip() for v in value.split(",")) if isinstance(value, str) \
        else tuple(value)
    if any(not isinstance(n, str) or not n for n in names) or len(set(names)) != len(names):
        raise OptionError(f"{option} must be distinct signal names, got {value!r}")
    return names


def _key(value: str | None, option: str) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or not value.strip():
        raise OptionError(f"{option} must be 'run_id' or a per-run fact's name, got {value!r}")
    return value.strip()


def check_count(value: int, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 0:
        raise OptionError(f"{name} must be a non-negative integer, got {value!r}")
    return int(value)


def check_alpha(alpha: float) -> float:
    if isinstance(alpha, bool) or not isinstance(alpha, numbers.Real) \
            or not math.isfinite(alpha) or not 0 < alpha < 1:
        raise OptionError(f"alpha must be a number in (0, 1), got {alpha!r}")
    return float(alpha)


def check_permutations(permutations: int) -> int:
    if isinstance(permutations, bool) or not isinstance(permutations, numbers.Integral) \
            or permutations < 1:
        raise OptionError(f"permutations must be a positive integer, got {permutations!r}")
    return int(permutations)
