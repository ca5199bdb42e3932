"""cfdesign: design, prove and run complementary filters for robot and UAV sensor fusion.

The symbolic engine (:mod:`cfdesign.symbolic`) turns a linear observer of a kinematic chain
(F, B, H, K) into the band transfer function of every sensor and proves exactly that the
bands sum to one.  The named filters of the source papers are small constructors on it.
:func:`design` turns a sensor specification into optimal gains (CARE, DARE, periodic DARE)
and a :class:`GainTable`.
"""

__version__ = "0.1.0"

from . import riccati
from .analysis import FrequencyResponse, frequency_response, transfer_functions
from .design import design, multirate_schedule
from .errors import CfdesignError, GainError, ProofError, RiccatiError, SpecError, StructureError
from .gains import GainTable, load_gains
from .plot import bode_plot
from .spec import FilterSpec, SensorSpec, example_path, load_spec, parse_spec
from .symbolic import (
                       STRUCTURES,
                       Observer,
                       Proof,
                       Sensor,
                       cf2,
                       cf3,
                       cfn,
                       ckf3,
                       ckf3_printed,
                       dckf3,
                       dckf3_printed,
                       eq32_denominator,
                       position,
                       prove,
                       structure,
)

__all__ = [
    "__version__",
    "CfdesignError", "SpecError", "StructureError", "GainError", "ProofError", "RiccatiError",
    "Observer", "Sensor", "Proof", "prove", "structure", "STRUCTURES",
    "cf2", "cf3", "ckf3", "dckf3", "cfn", "position", "ckf3_printed", "dckf3_printed", "eq32_denominator",
    "transfer_functions", "frequency_response", "FrequencyResponse", "bode_plot",
    "FilterSpec", "SensorSpec", "load_spec", "parse_spec", "example_path",
    "GainTable", "load_gains", "design", "multirate_schedule", "riccati",
]
