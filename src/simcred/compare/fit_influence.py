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
features) matrix and one product with the replicates' weights. ``D = X'c`` and ``G`` come from
the fit itself (:class:`~simcred.compare.transitions.GlobalFit`: its Gram matrix and per
(state, side) sums of its design rows, summed in the fit's own passes), so ``a`` costs one
more pass over the design rows. ``v`` is the regression of the shift's per-transition
coefficients ``c_t = ±w_s / N_side,s`` on the fit's columns, so ``X_t v`` is the part of the
shift's influence the fit can absorb. ``Σ_c a_c = 0`` (the normal
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
from simcred.compare.transitions import FIT_ROWS, Transitions


def shift_fit_influence(data: Transitions, entries: Entries, keep: np.ndarray
                        ) -> np.ndarray | None:
    """(clusters, features) ``a_c`` of the module docs; None when the fit was not kept (the
    bootstrap then holds the fit fixed)."""
    fit = data.fit
    if fit is None or not keep.any():
        return None
    level = data.effect_residual
    moment = np.einsum("sk,skp->p", _shift_coefficients(entries, keep), fit.column_sums)
    v = np.linalg.lstsq(fit.gram, moment, rcond=None)[0]  # D = X'c from the fit's sums
    cluster = np.repeat(entries.cluster, entries.count.astype(np.int64))
    parts = [slice(lo, lo + FIT_ROWS) for lo in range(0, len(level), FIT_ROWS)]

    def influence(i: int) -> np.ndarray:
        part = parts[i]
        absorbed = fit.design(fit.rows[part]) @ v
        return np.stack([np.bincount(cluster[part], weights=absorbed * level[part, j],
                                     minlength=entries.n_clusters)
                         for j in range(level.shape[1])], axis=1)

    out = np.zeros((entries.n_clusters, level.shape[1]))
    for piece in in_threads(influence, range(len(parts))):
        out += piece  # in order: the same sums
    return out


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
