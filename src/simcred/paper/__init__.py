"""Reproductions of the papers' experiments, with their qualitative claims checked.

Modules: ``claims`` (a claim: value against bound), ``seed000`` (Neurohr et al. sec. VI),
``seed002`` (Wagner, Groh et al.: reprocessing the cut-in, its variations), ``seed003`` (Braun et
al. on the cut-in), ``all`` (all three and the combined claims). Names are imported on first use.
"""

from simcred._lazy import lazy_getattr

_WHERE = {
    "Claim": "claims", "at_least": "claims", "below": "claims", "write_claims": "claims",
    "AllOptions": "all", "run_all": "all",
}
__all__ = sorted(_WHERE)
__getattr__ = lazy_getattr(__name__, _WHERE)
