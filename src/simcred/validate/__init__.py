"""The user's loop: one verdict for one test case from measured validity domains.

Above compare, contracts and sim; below report and cli. See docs/validate.md.
"""

from simcred.validate.loop import Validation, read_inputs, validate
from simcred.validate.simulate import simulate_candidates
from simcred.validate.spec import ValidationFileError, ValidationSpec, read_validation

__all__ = ["Validation", "ValidationFileError", "ValidationSpec", "read_inputs",
           "read_validation", "simulate_candidates", "validate"]
