"""Column statistics that put their temporaries in a caller's buffer.

A new array of millions of rows costs more to touch the first time than the arithmetic on it
(page faults: 1.1–2.6 s per GiB on the benchmark machine, docs/calibration.md), and
``ndarray.std`` makes one of its argument's size for the squared deviations. :func:`std_columns`
takes the same steps as NumPy's ``_var`` (sum, divide, subtract, square, sum, divide, square
root, each with the same ufunc on an array of the same layout), so its result is the same bit
for bit, with the squared deviations written into a buffer that a caller reuses.
"""

from __future__ import annotations

import numpy as np


def std_columns(values: np.ndarray, scratch: np.ndarray | None = None) -> np.ndarray:
    """``values.std(axis=0)`` of a float array (1-D: shape (1,)), its squared deviations
    written into ``scratch`` where it has ``values``' shape, type and strides (else a new
    array, as ``std`` makes)."""
    if scratch is None or scratch.shape != values.shape or scratch.dtype != values.dtype \
            or scratch.strides != values.strides:
        scratch = np.empty_like(values)
    count = np.intp(values.shape[0])
    mean = np.add.reduce(values, axis=0, keepdims=True)
    np.true_divide(mean, count, out=mean, casting="unsafe")
    deviation = np.subtract(values, mean, out=scratch)
    np.square(deviation, out=deviation)
    out = np.add.reduce(deviation, axis=0, keepdims=values.ndim == 1)
    np.true_divide(out, np.maximum(count, 0), out=out, casting="unsafe")
    return np.sqrt(out, out=out)
