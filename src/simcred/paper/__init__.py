"""Reproductions of the papers' experiments, with their qualitative claims checked.

Modules, one per paper, by topic: ``markov_chains`` (paper 000: Neurohr et al. sec. VI),
``reprocessing`` (paper 002: Wagner, Groh et al.: reprocessing the cut-in, its variations),
``validity_contracts`` (paper 003: Braun et al. on the cut-in); ``claims`` (a claim: value against
bound), ``all`` (all three and the combined claims). Names are imported on first use.
"""

from simcred._lazy import lazy_getattr

_WHERE = {
    "Claim": "claims", "at_least": "claims", "below": "claims", "write_claims": "claims",
    "AllOptions": "all", "run_all": "all",
}
__all__ = sorted(_WHERE)
__getattr__ = lazy_getattr(__name__, _WHERE)
