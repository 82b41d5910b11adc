"""The global fit's share of the shift's sampling variation: every bootstrap replicate of the
shift refitted to first order.

The effect is estimated from the response after the pooled global fit
(:attr:`~simcred.compare.transitions.Transitions.effect_residual`). A cluster bootstrap that
keeps the sample's fit in every replicate misses that every sample fits its own, and a fit
estimated on the sample absorbs part of that sample's between-cluster variation: the fixed-fit
bootstrap was 1.12–1.21 times the shift's sampling spread on the clip design (docs/calibration.md,
sessions 27–28). Refitting replicate ``r`` (cluster weights ``w_rc``) moves the residuals by
``−X (β_r − β̂)`` with ``β_r − β̂ = (Σ_c w_rc G_c)⁻¹ Σ_c w_rc X_c' r_c`` (``X`` the fit's
design rows, ``r`` the sample's residuals, ``G_c = X_c' X_c``). For given state weights the
shift is linear in the residuals, so the refitted replicate is ``shift_r(r) − shift_r(X)(β_r −
β̂)``; to first order (``shift_r(X) ≈ D``, the sample's shift of the design columns, and
``Σ_c w_rc G_c ≈ G = X'X``)::

    shift_r ≈ shift_r(fixed fit) − Σ_c w_rc a_c,   a_c = v' X_c' r_c,   v = G⁻¹ D

— the estimating-function bootstrap of the fit (Hu & Kalbfleisch 2000), one (clusters ×
features) matrix and one product with the replicates' weights. ``v`` is the regression of the
shift's per-transition coefficients ``c_t = ±w_s / N_side,s`` on the fit's columns, so ``X_t v``
is the part of the shift's influence the fit can absorb. ``Σ_c a_c = 0`` (the normal
equations), so the correction changes the replicates' spread, not their centre. The exact
refit moves the centre too, by second-order terms (the replicate's ``shift_r(X) − D`` times its
coefficient change) whose bootstrap mean estimates a bias that measured about 0 and whose
draw-to-draw noise cost every coverage cell 2–4 points (calibration.md, session 27).

References: Hu & Kalbfleisch, The estimating function bootstrap, Canadian J. Statistics 28,
2000; Kline & Santos, A score based approach to wild bootstrap inference, J. Econometric
Methods 1, 2012.
"""

from __future__ import annotations

import numpy as np

from simcred.compare.cluster_sums import Entries, normalised
from simcred.compare.threads import in_threads
from simcred.compare.transitions import FIT_ROWS, Basis, Transitions


def shift_fit_influence(data: Transitions, entries: Entries, keep: np.ndarray
                        ) -> np.ndarray | None:
    """(clusters, features) ``a_c`` of the module docs; None when the fit's covariates were not
    kept (the bootstrap then holds the fit fixed)."""
    if data.covariates is None or not keep.any():
        return None
    x, level = data.covariates, data.effect_residual
    design = _design_rows(x)
    count = entries.count.astype(np.int64)
    coefficient = np.repeat(_shift_coefficients(entries, keep)[entries.state, entries.side],
                            count)
    cluster = np.repeat(entries.cluster, count)
    parts = [slice(lo, lo + FIT_ROWS) for lo in range(0, len(x), FIT_ROWS)]

    def products(i: int) -> tuple[np.ndarray, np.ndarray]:
        rows = design(x[parts[i]])
        return rows.T @ rows, rows.T @ coefficient[parts[i]]

    gram, moment = 0.0, 0.0
    for part_gram, part_moment in in_threads(products, range(len(parts))):
        gram, moment = gram + part_gram, moment + part_moment  # in order: the same sums
    v = np.linalg.lstsq(gram, moment, rcond=None)[0]

    def influence(i: int) -> np.ndarray:
        part = parts[i]
        absorbed = design(x[part]) @ v
        return np.stack([np.bincount(cluster[part], weights=absorbed * level[part, j],
                                     minlength=entries.n_clusters)
                         for j in range(level.shape[1])], axis=1)

    out = np.zeros((entries.n_clusters, level.shape[1]))
    for piece in in_threads(influence, range(len(parts))):
        out += piece  # in order: the same sums
    return out


def _design_rows(x: np.ndarray):
    """The global fit's design matrix of rows ``x`` (its intercept alone where the fit is a
    mean; transitions.py)."""
    basis = Basis.of(x, cubic=True)
    if basis is None:
        return lambda rows: np.ones((len(rows), 1))
    return basis.design


def _shift_coefficients(entries: Entries, keep: np.ndarray) -> np.ndarray:
    """(states, 2) the shift's coefficient of a transition of each state and side:
    ``w_s / N_A,s`` and ``−w_s / N_B,s`` over the entering states (the sample's weights of
    :meth:`~simcred.compare.cluster_sums.ClusterSums.deviation`), 0 elsewhere."""
    count = entries.per_state(entries.count)
    total = entries.totals().sum(axis=0)
    share = np.where(keep, 0.5 * (count[:, 0] / total[0] + count[:, 1] / total[1]), 0.0)
    weight = normalised(share)
    with np.errstate(invalid="ignore", divide="ignore"):
        out = weight[:, None] / count * np.array([1.0, -1.0])
    return np.where(keep[:, None], out, 0.0)
