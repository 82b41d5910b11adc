"""Figures (matplotlib) and the self-contained HTML report; imports the domain, never the reverse.

Modules: ``figures`` (paper 000 heatmap and state map), ``markov_chains`` (Figs. 5-7),
``reprocessing`` (Figs. 3-8, and writing a reprocessing or variation result with its figures),
``html`` (the report of ``simcred paper all``). Names are imported on first use (matplotlib is
slow to import).
"""

from simcred._lazy import lazy_getattr

_WHERE = {
    "distance_heatmap": "figures", "state_map": "figures",
    "fig5_inputs": "markov_chains", "fig_distance_curves": "markov_chains",
    "write_figures": "reprocessing", "fig8_variations": "reprocessing",
    "write_reprocessed": "reprocessing", "write_variations": "reprocessing",
    "render_report": "html", "write_report": "html",
}
__all__ = sorted(_WHERE)
__getattr__ = lazy_getattr(__name__, _WHERE)
