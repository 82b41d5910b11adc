"""Physical units of variables and ports (pint)."""

from __future__ import annotations

from functools import cache

from simcred.errors import SimcredError


@cache
def _registry():
    import pint

    return pint.UnitRegistry()


def unit(text: str, *, where: str = ""):
    """The pint unit of ``text``; a one-line error naming ``where`` if it is not a unit."""
    try:
        return _registry().Unit(text)
    except Exception:  # pint raises several error types for unparsable units
        raise SimcredError(f"{where}: '{text}' is not a physical unit") from None


def same_unit(a: str, b: str) -> bool:
    """True when ``a`` and ``b`` name the same unit (``km/h`` == ``kilometer / hour``)."""
    return unit(a) == unit(b)
