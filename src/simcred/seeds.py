"""Seeds: the one place where randomness is derived (SPEC 7 style: ``seed`` at the boundary).

Every random stream in simcred is ``default_rng(SeedSequence(entropy, spawn_key=keys))``: run ``i``
of a campaign, variation ``i``, the permutation test of state ``s``. Results therefore depend only
on the seed and the keys, never on how work is split (serial, chunks, Dask workers).

- :func:`resolve_seed` turns the user's ``seed`` (int, Generator or None) into integer entropy,
  fresh from the OS when None (stored in the result so the run replays byte for byte);
- :func:`stream` is the generator of one keyed stream;
- :func:`derive_seed` is an integer seed of an independent sub-campaign (e.g. one λ of a sweep).
"""

from __future__ import annotations

import numbers

import numpy as np

from simcred.errors import OptionError

__all__ = ["derive_seed", "resolve_seed", "stream"]


def resolve_seed(seed: int | np.random.Generator | None) -> int:
    """The integer entropy behind ``seed``: fresh if None, one draw from a Generator."""
    if seed is None:
        return int(np.random.SeedSequence().entropy)
    if isinstance(seed, np.random.Generator):
        return int(seed.integers(2**63))
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise OptionError(f"seed must be a non-negative integer or a numpy Generator, got {seed!r}")
    return int(seed)


def stream(seed: int, *keys: int) -> np.random.Generator:
    """The random stream with ``keys`` under ``seed`` (e.g. run ``i``: ``stream(seed, i)``).

    >>> float(stream(0, 3).random()) == float(stream(0, 3).random())
    True
    """
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=keys))


def derive_seed(seed: int, *keys: int) -> int:
    """A campaign seed derived from ``seed`` and integer ``keys`` (independent streams)."""
    words = np.random.SeedSequence(seed, spawn_key=keys).generate_state(2, np.uint32)
    return int(words[0]) << 32 | int(words[1])
