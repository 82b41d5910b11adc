"""Shared timing helper of the benchmark scripts."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def best_of(fn: Callable[[], T], repeats: int) -> tuple[float, T]:
    """Best wall-clock seconds of ``repeats`` calls, and the last result."""
    best, out = float("inf"), None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - start)
    return best, out


def machine() -> dict[str, object]:
    """What the numbers were measured on."""
    import os
    import platform

    import numpy as np

    return {"cpus": os.cpu_count(), "python": platform.python_version(),
            "machine": platform.machine(), "numpy": np.__version__}


def save_results(path, results: dict) -> None:
    """Write ``results`` as indented JSON and say where."""
    import json

    path.parent.mkdir(exist_ok=True)
    path.write_text(json.dumps(results, indent=1, ensure_ascii=False) + "\n")
    print(f"wrote {path}")
