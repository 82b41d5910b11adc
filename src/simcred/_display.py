"""Rich notebook display: ``_repr_html_`` of results, drawn by a module of the report layer.

Domain objects (a trace set, a comparison, a validation) do not import the report layer
(docs/architecture.md), yet a notebook shows them as a table and a figure. As pandas chooses
its plotting backend by module name (``pandas.options.plotting.backend``), the domain's
``_repr_html_`` hands itself to the renderer module named here, imported when a notebook first
asks for HTML; the renderer knows the types and draws them.
"""

from __future__ import annotations

import importlib
from typing import Any

#: the module whose ``html(obj) -> str`` draws simcred objects for notebooks
RENDERER = "simcred.report.notebook"


def html(obj: Any) -> str:
    """The notebook HTML of ``obj`` (a summary table and, where there is one, a figure)."""
    return importlib.import_module(RENDERER).html(obj)
