"""A distance matrix draws the run-level test's permutations once per size of pair
(``runs.AssignmentDraw``): the rows are those each pair's test would draw itself, used only
where they are, so every pair's JSON is ``compare``'s."""

from __future__ import annotations

import numpy as np
import pytest

from helpers import ar_set
from simcred.compare import compare, matrix
from simcred.compare.runs import AssignmentDraw, PackedAssignments, batch_size
from simcred.engine import Engine


@pytest.mark.parametrize("n_runs, n_a, permutations, n_cols",
                         [(9, 4, 5, 3), (64, 30, 99, 64), (203, 101, 2000, 0)])
def test_a_draw_is_the_tests_own_draw(n_runs, n_a, permutations, n_cols):
    in_a = np.arange(n_runs) < n_a
    draw = AssignmentDraw.of(n_a, n_runs, permutations, np.random.default_rng(4))
    own = PackedAssignments.random(in_a, permutations, n_cols, np.random.default_rng(4))
    assert draw.fits(in_a, permutations, n_cols)
    assert np.array_equal(draw.assignments.bits, own.bits)


def test_a_draw_fits_no_other_test():
    draw = AssignmentDraw.of(30, 64, 999, np.random.default_rng(4))
    first_30 = np.arange(64) < 30
    assert draw.fits(first_30, 999, 100)
    assert not draw.fits(first_30, 499, 100)  # other permutations
    assert not draw.fits(np.arange(64) < 31, 999, 100)  # another split
    assert not draw.fits(np.arange(65) < 30, 999, 100)  # more runs
    assert not draw.fits(first_30[::-1].copy(), 999, 100)  # A's runs not first
    wide = 2**22 // 900  # a count matrix this wide draws in batches of 900, not 1,024
    assert batch_size(wide, 64) != batch_size(64)
    assert not draw.fits(first_30, 999, wide)


class Recording(Engine):
    """In-process, recording the tasks kept by name; given ``owners``, "distributed" with set k
    held by worker ``owners[k]`` (the distributed split of the pairs then runs here)."""

    def __init__(self, owners: list[str] | None = None) -> None:
        self.kept: list[str] = []
        self.owners, self.distributed = owners, owners is not None

    def holders(self, handles):
        return list(self.owners)

    def keep(self, task, items, near=None):
        self.kept.extend([task.__name__] * len(items))
        return super().keep(task, items, near)


@pytest.mark.parametrize("distributed", [False, True])
def test_matrix_draws_once_per_size_and_equals_compare(distributed):
    """Sizes 40, 40, 40, 55: two sizes of pair, each shared by three pairs, drawn once each;
    in-process and on the distributed path (sets held by two named workers)."""
    rng = np.random.default_rng(9)
    sets = [ar_set(rng, n, phi, length=60, source=f"s{k}")
            for k, (n, phi) in enumerate([(40, 0.6), (40, 0.6), (40, -0.3), (55, 0.2)])]
    options = dict(features=["x", "y"], bins=4, permutations=49, seed=5)
    runner = Recording(["w1", "w2", "w2", "w1"] if distributed else None)
    result = matrix(sets, runner=runner, **options)
    assert runner.kept.count("_draw") == 2
    assert runner.kept.count("_pair_side") == (4 if distributed else 0)
    for (i, j), comparison in zip(result.pairs, result.comparisons, strict=True):
        assert comparison.to_json() == compare(sets[i], sets[j], **options).to_json()
