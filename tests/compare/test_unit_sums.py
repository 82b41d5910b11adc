"""unit_matrix: the dense and the sparse layout against a literal per-entry construction."""

from __future__ import annotations

import numpy as np
import pytest

from simcred.compare import unit_sums


def _parts(rng: np.random.Generator, n_units: int, n_blocks: int, fill: float):
    """Two parts of widths 3 and 2 whose (unit, block) positions overlap in part."""
    parts = []
    for width in (3, 2):
        cells = np.flatnonzero(rng.random(n_units * n_blocks) < fill)
        rng.shuffle(cells)  # any order
        values = rng.normal(size=(len(cells), width))
        parts.append((cells // n_blocks, cells % n_blocks, values))
    return parts


def _literal(parts, n_units, n_blocks, products):
    rows: dict[tuple[int, int], np.ndarray] = {}
    offset = 0
    for unit, block, values in parts:
        for u, b, v in zip(unit, block, values, strict=True):
            rows.setdefault((int(u), int(b)), np.zeros(5))[offset:offset + len(v)] = v
        offset += values.shape[1]
    width = 5 if products is None else len(products[0])
    out = np.zeros((width * n_blocks, n_units))
    for (u, b), row in rows.items():
        for c in range(width):
            if products is None:
                value = row[c]
            else:
                one, two = products[0][c], products[1][c]
                value = row[one] * (row[two] if two >= 0 else 1.0)
            out[c * n_blocks + b, u] = value
    return out


@pytest.mark.parametrize("dense_share", [0.0, 2.0])  # every layout dense / every one sparse
@pytest.mark.parametrize("with_products", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_unit_matrix_equals_literal(monkeypatch, dense_share, with_products, seed):
    monkeypatch.setattr(unit_sums, "DENSE_SHARE", dense_share)
    rng = np.random.default_rng(seed)
    n_units, n_blocks = 7, 4
    parts = _parts(rng, n_units, n_blocks, fill=0.6)
    products = (np.array([0, 1, 3, 4, 2]), np.array([-1, 1, 0, -1, 4])) if with_products \
        else None
    matrix = unit_sums.unit_matrix(parts, n_units, n_blocks, products=products)
    assert isinstance(matrix, np.ndarray | unit_sums.ProductColumns) == (dense_share == 0.0)
    np.testing.assert_array_equal(matrix @ np.eye(n_units),
                                  _literal(parts, n_units, n_blocks, products))


@pytest.mark.parametrize("chunk", [1, 20, 10**6])  # one block at a time, some, all at once
def test_product_columns_in_chunks(monkeypatch, chunk):
    """The products formed in chunks of blocks give the whole matrix's product."""
    monkeypatch.setattr(unit_sums, "DENSE_SHARE", 0.0)
    monkeypatch.setattr(unit_sums, "CHUNK_ELEMENTS", chunk)
    rng = np.random.default_rng(7)
    n_units, n_blocks = 6, 5
    parts = _parts(rng, n_units, n_blocks, fill=0.7)
    products = (np.array([0, 3, 2]), np.array([4, -1, 2]))
    weights = rng.integers(0, 3, (n_units, 4)).astype(np.float64)
    expected = _literal(parts, n_units, n_blocks, products) @ weights
    got = unit_sums.unit_matrix(parts, n_units, n_blocks, products=products) @ weights
    np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)
