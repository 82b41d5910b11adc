"""Figures (matplotlib) and the self-contained HTML report; imports the domain, never the reverse.

Modules: ``figures`` (seed-000 heatmap and state map), ``seed000`` (Figs. 5-7), ``seed002``
(Figs. 3-8, and writing a reprocessing or variation result with its figures), ``html`` (the
report of ``simcred paper all``). Names are imported on first use (matplotlib is slow to import).
"""

from simcred._lazy import lazy_getattr

_WHERE = {
    "distance_heatmap": "figures", "state_map": "figures",
    "fig5_inputs": "seed000", "fig_distance_curves": "seed000",
    "write_figures": "seed002", "fig8_variations": "seed002",
    "write_reprocessed": "seed002", "write_variations": "seed002",
    "render_report": "html", "write_report": "html",
}
__all__ = sorted(_WHERE)
__getattr__ = lazy_getattr(__name__, _WHERE)
