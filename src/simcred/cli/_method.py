"""One option group for the comparison method, generated from the fields of
:class:`~simcred.compare.method.Method`, shared by ``simcred compare`` and ``simcred matrix``.

:func:`method_options` gives a command one ``--option`` per field (help, flags, default and the
commands that offer it come from the field's metadata) and hands the command the given values;
:func:`build_method` turns them into the method. A field of a plain type (a number, a flag, a
text, a choice) needs nothing here; one that the command line writes as text (``10,8``,
``v=0.1,gap=0.3``) names its parser in :data:`PARSERS`.
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import inspect
import types
import typing
from collections.abc import Callable
from typing import Annotated, Any

import typer

from simcred.cli._app import Seed
from simcred.compare.method import Method
from simcred.compare.mmd import Test
from simcred.errors import OptionError
from simcred.limits import check_count, check_finite

#: Below this, 1/alpha and log(1/alpha) lose the precision the bound and the p-values need.
MIN_ALPHA = 1e-15


def split(text: str | None) -> list[str] | None:
    return None if text is None else [part.strip() for part in text.split(",")]


def parse_bins(text: str) -> int | list[int]:
    try:
        values = [int(part) for part in text.split(",")]
    except ValueError:
        raise OptionError(f"--bins must be an integer or a comma-separated list, got {text!r}"
                          ) from None
    for value in values:
        check_count(value, "bins", "--bins", minimum=2)
    return values[0] if len(values) == 1 else values


def parse_margin(text: str | None) -> float | dict[str, float] | None:
    """``0.2`` (every response feature) or ``v=0.1,gap=0.3``."""
    if text is None:
        return None
    try:
        if "=" not in text:
            return float(text)
        pairs = [part.split("=") for part in text.split(",")]
        return {name.strip(): float(value) for name, value in pairs}
    except ValueError:
        raise OptionError(f"--margin must be a number or FEATURE=NUMBER,...; got {text!r}"
                          ) from None


def check_alpha(alpha: float) -> float:
    return check_finite(alpha, "--alpha", minimum=MIN_ALPHA, maximum=1, open_maximum=True)


#: Fields the command line writes as text, with the parser that makes the field's value.
PARSERS: dict[str, Callable[[Any], Any]] = {
    "features": split, "bins": parse_bins, "inputs": lambda text: split(text) or (),
    "margin": parse_margin,
}
#: Checks the command line makes before any work (its own limits, messages naming the flag),
#: in this order.
CHECKS: dict[str, Callable[[Any], Any]] = {
    "baseline": lambda n: check_count(n, "permutations", "--baseline", minimum=0),
    "bootstrap": lambda n: check_count(n, "permutations", "--bootstrap", minimum=0),
    "alpha": check_alpha,
    "permutations": lambda n: check_count(n, "permutations", "--permutations"),
}
#: Options declared by the command line for every command (shared with other commands).
SHARED = {"seed": Seed}


def fields_of(command: str, method: type = Method) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(method) if command in f.metadata["commands"]]


def _cli_type(field: dataclasses.Field, hint: Any) -> Any:
    """The option's type: the field's own where the command line has it (number, flag, text,
    choice; optional), text where the field names a parser."""
    if field.name in PARSERS:
        return str | None
    args = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
    plain = [a for a in args if a is not type(None)]
    if len(plain) != 1 or not (plain[0] in (int, float, bool, str)
                               or issubclass(plain[0], enum.Enum)):
        raise TypeError(f"Method.{field.name}: no command-line type for {hint}; name a parser "
                        "in simcred.cli._method.PARSERS")
    return plain[0] | None if len(args) > 1 else plain[0]


def _default(field: dataclasses.Field) -> Any:
    default = field.metadata["cli_default"]
    if default is dataclasses.MISSING:
        default = field.default
    if field.name in PARSERS:  # written as text
        return None if default in (None, ()) else str(default)
    return default


def parameters(command: str, method: type = Method) -> list[inspect.Parameter]:
    """One keyword parameter per field of ``method`` that ``command`` offers, as typer reads
    them (an ``Annotated`` type with its ``typer.Option``)."""
    hints = typing.get_type_hints(method)
    return [_parameter(field, hints[field.name]) for field in fields_of(command, method)]


def parameter(name: str) -> inspect.Parameter:
    """The option of the method's field ``name`` (for a command that offers it alone)."""
    field = next(f for f in dataclasses.fields(Method) if f.name == name)
    return _parameter(field, typing.get_type_hints(Method)[name])


def _parameter(field: dataclasses.Field, hint: Any) -> inspect.Parameter:
    annotation = SHARED.get(field.name) or Annotated[
        _cli_type(field, hint), typer.Option(*field.metadata["flags"],
                                             help=field.metadata["help"])]
    return inspect.Parameter(field.name, inspect.Parameter.KEYWORD_ONLY,
                             default=_default(field), annotation=annotation)


def method_options(command: str, method: type = Method) -> Callable[[Callable], Callable]:
    """Decorator: the command's parameter ``method`` becomes the method's options (in its
    place, in field order); the command receives their values as a dict ``method``."""

    def decorate(function: Callable) -> Callable:
        signature = inspect.signature(function, eval_str=True)
        generated = parameters(command, method)
        names = [p.name for p in generated]
        params = []
        for p in signature.parameters.values():
            params.extend(generated if p.name == "method" else
                          [p.replace(kind=inspect.Parameter.KEYWORD_ONLY)])

        @functools.wraps(function)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            values = {name: kwargs.pop(name) for name in names}
            return function(*args, method=values, **kwargs)

        wrapper.__signature__ = signature.replace(parameters=params)
        return wrapper

    return decorate


def build_method(values: dict[str, Any]) -> Method:
    """The method of the given option values: the command line's checks, then its parsers;
    an option that does not apply to the chosen test is left out (metadata ``tests``)."""
    for name, check in CHECKS.items():
        if name in values:
            check(values[name])
    test = Test(values.get("test", Test.RUNS))
    given = {}
    for field in dataclasses.fields(Method):
        if field.name not in values:
            continue
        tests = field.metadata["tests"]
        if tests is not None and test.value not in tests:
            continue
        value = values[field.name]
        given[field.name] = PARSERS[field.name](value) if field.name in PARSERS else value
    return Method(**given)
