"""simcred: can I trust this simulation for this test case?

Validity of simulation models for testing automated driving, after Neurohr et al. 2023 (comparison
of run sets), Wagner, Groh et al. (reprocessing of real drives) and Braun et al. (contracts).
"""

import simcred.io  # noqa: F401  (registers the file formats of TraceSet.read / write)
from simcred._version import __version__
from simcred.errors import OptionError, SimcredError, TraceSetError
from simcred.traces import TraceSet

__all__ = ["TraceSet", "SimcredError", "TraceSetError", "OptionError", "__version__"]
