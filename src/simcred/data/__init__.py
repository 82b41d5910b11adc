"""Real data shipped with simcred, so an installed copy can run its studies without other files.

- ``openacc/``: JRC OpenACC car following on the ZalaZONE test track (Makridis et al. 2021), one
  zstd Parquet file per recording with time, speeds and gaps; CC BY 4.0.
- ``a9/``: the OSC-Generator A9 highway recording (sensor-data CSV, 10 Hz); Apache-2.0.
- ``contracts/vehicle.yaml``: the contract library of ``simcred paper 003`` (SimpleCar/KS/ST,
  sensors, the AD function); ``examples/contracts/vehicle.yaml`` in the repository links here.

Each folder holds its licence and attribution next to the data. :func:`path` gives the file of a
name relative to this package (``path("a9/trajectories_file.csv")``); the command line offers the
same as ``simcred data path NAME``.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

from simcred.errors import TraceSetError

__all__ = ["path", "names"]


def _root() -> Path:
    return Path(str(resources.files(__name__)))


def path(name: str) -> Path:
    """The shipped file or folder ``name`` (a relative path such as ``"a9/trajectories_file.csv"``).

    Raises
    ------
    TraceSetError
        If ``name`` is absolute, leaves the data folder, or names nothing shipped.

    Examples
    --------
    >>> path("a9/trajectories_file.csv").name
    'trajectories_file.csv'
    """
    root = _root().resolve()
    relative = Path(name)
    target = (root / relative).resolve()
    if relative.is_absolute() or root not in (target, *target.parents) or target == root:
        raise TraceSetError(f"{name}: not a name inside simcred's data folder (e.g. "
                            "'a9/trajectories_file.csv')")
    if not target.exists() or target.name.startswith(("__", ".")):
        raise TraceSetError(f"{name}: no such shipped data (have: {', '.join(names())})")
    return target


def names() -> list[str]:
    """Every shipped data file, as names :func:`path` accepts, sorted."""
    root = _root()
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*")
                  if p.is_file() and p.suffix not in (".py", ".pyc")
                  and "__pycache__" not in p.parts)
