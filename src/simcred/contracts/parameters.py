"""Constant parameters of a model (paper 003 sec. III: a model's behaviour may depend on settings
that the contract states over; Benveniste et al. 2018, sec. 4, parametric contracts).

A model declares parameters with ranges (``mu: {range: [0.5, 1.0]}``) and its contract may use
them (``ego.v <= 40 * mu``). The library does not know which value a run of the model uses, only
that it lies in the range, so simcred reasons with the contract that the model satisfies
*whatever* the value is — the join of the contracts C(p) over the range R:

    A = ∀p ∈ R. A(p)                 (the operating conditions valid for every setting)
    G' = ∃p ∈ R. (A(p) → G(p))       (what some setting — the one in use — guarantees)

A model satisfying C(p*) for its actual p* ∈ R satisfies (A, G') (A ⊆ A(p*) and
A(p*) → G(p*) ⊆ G'), so every certificate built on it is sound. The quantifiers are eliminated
with z3 (linear real arithmetic); the result is over the model's ports only. Where z3 cannot
eliminate them (nonlinear use of a parameter), the library is refused with a one-line error.
"""

from __future__ import annotations

from collections.abc import Mapping
from fractions import Fraction

from simcred.contracts.algebra import Contract
from simcred.contracts.expr import ExpressionError, variables
from simcred.contracts.readable import within
from simcred.contracts.smt import to_z3, z3_variables

DEFAULT_TIMEOUT_MS = 5_000


def eliminate(contract: Contract, ranges: Mapping[str, tuple[Fraction, Fraction]], *,
              types: Mapping[str, str] | None = None, where: str = "",
              timeout_ms: int = DEFAULT_TIMEOUT_MS) -> Contract:
    """The contract over the non-parameter variables that holds for every parameter value in
    ``ranges`` (module docs); a one-line :class:`ExpressionError` if z3 cannot eliminate."""
    import z3

    from simcred.contracts.project import _eliminate, from_z3

    used = sorted(contract.variables & set(ranges))
    if not used:
        return contract
    env = z3_variables(contract.variables, types)
    params = [env[p] for p in used]
    inside = z3.And([z3.And(env[p] >= _real(ranges[p][0]), env[p] <= _real(ranges[p][1]))
                     for p in used])
    assumption = z3.ForAll(params, z3.Implies(inside, to_z3(contract.assumption, env)))
    guarantee = z3.Exists(params, z3.And(inside, to_z3(contract.saturated_guarantee, env)))
    try:
        a, g = from_z3(_eliminate(assumption, timeout_ms)), from_z3(_eliminate(guarantee,
                                                                                 timeout_ms))
    except (z3.Z3Exception, NotImplementedError):
        a = g = None
    if a is None or (variables(a) | variables(g)) & set(used):
        raise ExpressionError(f"{where}: cannot eliminate the parameter(s) {', '.join(used)} "
                              "(use them linearly: e.g. 'v <= 40 m/s * mu', not "
                              "'v * mu <= 40 m/s')")
    # the same contract in readable form: the assumption tidied, the guarantee simplified where
    # the assumption holds (readable.within: equivalences only)
    a = within(a, types=types)
    return Contract(a, within(g, a, types=types), contract.name)


def _real(value: Fraction):
    import z3

    value = Fraction(value)
    return z3.RealVal(f"{value.numerator}/{value.denominator}")
