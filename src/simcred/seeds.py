"""Seeds: the one place where randomness is derived (SPEC 7 style: ``seed`` at the boundary).

Every random stream in simcred is ``default_rng(SeedSequence(entropy, spawn_key=keys))``: run ``i``
of a campaign, variation ``i``, the permutation test of state ``s``. Results therefore depend only
on the seed and the keys, never on how work is split (serial, chunks, Dask workers).

- :func:`resolve_seed` turns the user's ``seed`` (int, Generator or None) into integer entropy,
  fresh from the OS when None (stored in the result so the run replays byte for byte);
- :func:`stream` is the generator of one keyed stream;
- :func:`derive_seed` is an integer seed of an independent sub-campaign (e.g. one λ of a sweep);
- :func:`named_seed` and :func:`sumo_episode_seed` are seeds keyed by a *name* (a candidate, a
  study row, an episode's run id) instead of an index, so they do not depend on the order of
  the names.

Why two name schemes remain: :func:`named_seed` keys by the name's CRC-32 and gives 63 bits
(every per-cell comparison of ``validate`` and ``study``); :func:`sumo_episode_seed` keys by the
first 8 bytes of the name's SHA-256 and gives the 31 bits SUMO's ``--seed`` takes. Folding one
into the other would change every verdict, study or SUMO replay made so far, so both stay, here
and nowhere else.
"""

from __future__ import annotations

import hashlib
import numbers
import zlib

import numpy as np

from simcred.errors import OptionError

__all__ = ["derive_seed", "named_seed", "resolve_seed", "stream", "sumo_episode_seed"]


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


def named_stream(seed: int, name: str, *keys: int) -> np.random.Generator:
    """The random stream keyed by ``name`` (its CRC-32) and integer ``keys`` under ``seed``
    (:func:`stream` with the name as its first key; e.g. one candidate's sensor draws).

    >>> a, b = named_stream(0, "idm", 1), stream(0, zlib.crc32(b"idm"), 1)
    >>> float(a.random()) == float(b.random())
    True
    """
    return stream(seed, zlib.crc32(name.encode()), *keys)


def named_seed(seed: int, name: str, *keys: int) -> int:
    """A 63-bit seed keyed by ``name`` (its CRC-32) and integer ``keys``: independent of the
    order in which names come (a validation's candidates and cells, a study's rows).

    >>> named_seed(0, "idm", 3) == named_seed(0, "idm", 3) != named_seed(0, "krauss", 3)
    True
    """
    sequence = np.random.SeedSequence(seed, spawn_key=(zlib.crc32(name.encode()), *keys))
    return int(sequence.generate_state(1, np.uint64)[0] >> np.uint64(1))


def sumo_episode_seed(seed: int, name: str) -> int:
    """SUMO's ``--seed`` (31 bits) for the episode named ``name``: ``SeedSequence(seed,
    (h,))`` with ``h`` the first 8 bytes of the name's SHA-256 (little-endian)."""
    key = int.from_bytes(hashlib.sha256(name.encode()).digest()[:8], "little")
    return int(np.random.SeedSequence(seed, spawn_key=(key,)).generate_state(1)[0] & 0x7FFFFFFF)
