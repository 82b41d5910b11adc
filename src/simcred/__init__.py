"""simcred: can I trust this simulation for this test case?

Validity of simulation models for testing automated driving, after Neurohr et al. 2023 (comparison
of run sets), Wagner, Groh et al. (reprocessing of real drives) and Braun et al. (contracts).
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("simcred")
except PackageNotFoundError:  # pragma: no cover - running from a source tree without install
    __version__ = "0+unknown"

from simcred.errors import OptionError, SimcredError, TraceSetError  # noqa: E402
from simcred.traces import TraceSet  # noqa: E402

__all__ = ["TraceSet", "SimcredError", "TraceSetError", "OptionError", "__version__"]
