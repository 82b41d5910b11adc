"""Name-derived seeds live in simcred.seeds only (issue 27); the two schemes give the seeds
they gave before the move (verdicts, studies and SUMO replays keep their bytes)."""

from __future__ import annotations

import hashlib
import zlib

import numpy as np
import pytest

from simcred.regions.engine import cell_seed
from simcred.seeds import named_seed, sumo_episode_seed
from simcred.sim.sumo import episode_seed

NAMES = ["idm", "krauss", "plan:halves", "tolerance:cmp", "run_1", "ACC/x@17", "ü"]


def _crc32_literal(seed: int, name: str, cell: int) -> int:  # regions.cell_seed before the move
    sequence = np.random.SeedSequence(seed, spawn_key=(zlib.crc32(name.encode()), cell))
    return int(sequence.generate_state(1, np.uint64)[0] >> np.uint64(1))


def _sha256_literal(seed: int, run_id: str) -> int:  # sim.sumo.episode_seed before the move
    key = int.from_bytes(hashlib.sha256(run_id.encode()).digest()[:8], "little")
    return int(np.random.SeedSequence(seed, spawn_key=(key,)).generate_state(1)[0] & 0x7FFFFFFF)


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("seed", [0, 1, 2**40 + 3])
def test_both_schemes_give_the_seeds_they_gave(seed, name):
    for cell in (0, 5):
        assert named_seed(seed, name, cell) == cell_seed(seed, name, cell) \
            == _crc32_literal(seed, name, cell)
    assert sumo_episode_seed(seed, name) == episode_seed(seed, name) \
        == _sha256_literal(seed, name)
    assert 0 <= sumo_episode_seed(seed, name) < 2**31 and 0 <= named_seed(seed, name) < 2**63


def test_pinned_values():
    assert named_seed(0, "idm", 3) == 7215813296101075106
    assert sumo_episode_seed(7, "run_1") == 1371024054
