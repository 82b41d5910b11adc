"""Bounded temporal operators (issue 15, item 3) against rtamt, the peer STL library.

1,000+ random formulas (always, eventually, historically, once, previous, until, since over
and/or/not/implies of comparisons), each on its own random signals: our robustness equals
rtamt's discrete-time offline robustness at every sample, and our Boolean verdict is
"robustness > 0" wherever the robustness is not 0. Also: windows on non-uniform sampling and
across runs against a literal (loop) implementation, the monitor on temporal clauses, and the
z3 algebra refusing temporal clauses.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from simcred.contracts.algebra import Contract, refines
from simcred.contracts.evaluate import evaluate, margin
from simcred.contracts.expr import Compare, ExpressionError, Logic, Num, Temporal, Var, to_text
from simcred.contracts.parse import parse
from simcred.contracts.temporal import Timeline

rtamt = pytest.importorskip("rtamt")

FORMULAS = 1_200
UNARY = ("always", "eventually", "historically", "once")


def random_formula(rng, depth: int = 0):
    kind = rng.integers(0, 10) if depth < 3 else 0
    if kind <= 2:
        name = ("x", "y")[rng.integers(0, 2)]
        op = ("<=", "<", ">=", ">")[rng.integers(0, 4)]
        return Compare(op, Var(name), Num(Fraction(f"{rng.normal():.2f}")))
    if kind <= 4:
        lo = int(rng.integers(0, 3))
        return Temporal(UNARY[rng.integers(0, 4)], lo, lo + int(rng.integers(0, 4)),
                        (random_formula(rng, depth + 1),))
    if kind == 5:
        return Temporal("previous", 0, 0, (random_formula(rng, depth + 1),))
    if kind == 6:
        lo = int(rng.integers(0, 2))
        return Temporal(("until", "since")[rng.integers(0, 2)], lo, lo + int(rng.integers(0, 4)),
                        (random_formula(rng, depth + 1), random_formula(rng, depth + 1)))
    if kind == 7:
        return Logic("not", (random_formula(rng, depth + 1),))
    if kind == 8:
        return Logic("implies", (random_formula(rng, depth + 1), random_formula(rng, depth + 1)))
    return Logic(("and", "or")[rng.integers(0, 2)],
                 (random_formula(rng, depth + 1), random_formula(rng, depth + 1)))


def rtamt_text(e) -> str:
    """The same formula in rtamt's syntax (every operand parenthesised)."""
    if isinstance(e, Compare):
        return f"({e.left.name} {e.op} {float(e.right.value)})"
    if isinstance(e, Logic):
        if e.op == "not":
            return f"(not {rtamt_text(e.args[0])})"
        return "(" + f" {e.op} ".join(rtamt_text(a) for a in e.args) + ")"
    if e.op == "previous":
        return f"(prev {rtamt_text(e.args[0])})"
    window = f"[{int(e.lo)},{int(e.hi)}]"
    if e.op in ("until", "since"):
        return f"({rtamt_text(e.args[0])} {e.op}{window} {rtamt_text(e.args[1])})"
    return f"({e.op}{window} {rtamt_text(e.args[0])})"


def rtamt_robustness(e, x, y) -> np.ndarray:
    spec = rtamt.StlDiscreteTimeSpecification()
    spec.declare_var("x", "float")
    spec.declare_var("y", "float")
    spec.spec = rtamt_text(e)
    spec.set_sampling_period(1, "s", 0.1)
    spec.parse()
    out = spec.evaluate({"time": list(range(len(x))), "x": x.tolist(), "y": y.tolist()})
    return np.array([v for _, v in out], dtype=float)


def test_robustness_and_verdict_equal_rtamt_on_random_formulas_and_signals():
    rng = np.random.default_rng(20261123)
    checked = 0
    for _ in range(FORMULAS):
        e = random_formula(rng)
        e = parse(to_text(e))  # through our own text: the parser is part of what is tested
        n = int(rng.integers(2, 14))  # rtamt fails on one-sample traces (its own bug)
        x, y = rng.normal(size=n).round(3), rng.normal(size=n).round(3)
        expected = rtamt_robustness(e, x, y)
        columns, timeline = {"x": x, "y": y}, Timeline.single(np.arange(n, dtype=float))
        robustness = np.broadcast_to(margin(e, columns, timeline), (n,))
        np.testing.assert_allclose(robustness, expected, rtol=0, atol=1e-9,
                                   err_msg=to_text(e))
        verdict = np.broadcast_to(evaluate(e, columns, timeline), (n,))
        decided = expected != 0
        assert (verdict[decided] == (expected[decided] > 0)).all(), to_text(e)
        checked += 1
    assert checked >= 1_000


def literal_window(time, offsets, values, lo, hi, *, past, reduce, empty):
    """Loop oracle: reduce ``values`` over each sample's window within its run."""
    out = []
    for r in range(len(offsets) - 1):
        a, b = offsets[r], offsets[r + 1]
        for i in range(a, b):
            t = time[i]
            inside = [values[j] for j in range(a, b)
                      if (t - hi <= time[j] <= t - lo if past else t + lo <= time[j] <= t + hi)]
            out.append(reduce(inside) if inside else empty)
    return np.array(out)


@pytest.mark.parametrize("seed", range(20))
def test_windows_on_non_uniform_sampling_and_several_runs(seed):
    rng = np.random.default_rng(seed)
    lengths = rng.integers(1, 12, size=3)
    time = np.concatenate([np.cumsum(rng.choice([0.125, 0.25, 0.5], size=k)) for k in lengths])
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    x = rng.normal(size=len(time))
    timeline = Timeline(time, offsets)
    for op, past, reduce, empty in (("always", False, min, np.inf),
                                    ("eventually", False, max, -np.inf),
                                    ("historically", True, min, np.inf),
                                    ("once", True, max, -np.inf)):
        lo, hi = sorted(rng.choice([0, 0.25, 0.5, 1.0], size=2))
        e = parse(f"{op}[{lo}, {hi}] x <= 0")
        expected = literal_window(time, offsets, -x, lo, hi, past=past, reduce=reduce,
                                  empty=empty)
        np.testing.assert_allclose(margin(e, {"x": x}, timeline), expected, atol=1e-12)


def test_monitor_reports_temporal_clauses(tmp_path):
    from simcred.contracts.monitor import monitor
    from simcred.traces import TraceSet

    t = np.arange(0, 5, 0.5)
    v = np.array([0, 0, 0, 3, 0, 0, 0, 0, 3, 3], dtype=float)
    traces = TraceSet(("v",), t, v[:, None], np.array([0, len(t)]), ("r0",))
    contract = Contract.from_strings("true", "v > 1 implies eventually[0, 1] v <= 1")
    report = monitor(traces, {"M": contract})
    assert [(w.first_step, w.last_step) for w in report.violations] == [(8, 9)]


def test_the_algebra_refuses_temporal_clauses_clearly():
    a = Contract.from_strings("always[0, 2] x <= 1", "y <= 1")
    with pytest.raises(ExpressionError, match="temporal: the contract algebra"):
        refines(a, a)


def test_temporal_evaluation_needs_runs():
    with pytest.raises(ExpressionError, match="needs recorded runs"):
        evaluate(parse("always[0, 1] x <= 1"), {"x": np.zeros(3)})


@pytest.mark.parametrize("text", ["always[2, 1] x <= 1", "eventually[-1, 1] x <= 1",
                                  "always[0, 1] x + 1", "x until[0, 1] y <= 1"])
def test_bad_windows_and_operands_are_one_line_errors(text):
    with pytest.raises(ExpressionError):
        parse(text)
