"""Symbolic side of cfdesign: the observer engine, the named filters and the proofs.

This is the only package of cfdesign that imports sympy.
"""

from .filters import (
                      STRUCTURES,
                      cf2,
                      cf3,
                      cfn,
                      ckf3,
                      ckf3_printed,
                      dckf3,
                      dckf3_printed,
                      eq32_denominator,
                      position,
                      structure,
)
from .observer import Observer, Sensor, discrete_relation, integrator_chain, zoh, zoh_chain
from .proof import Proof, prove

__all__ = ["Observer", "Sensor", "Proof", "prove", "discrete_relation", "integrator_chain", "zoh", "zoh_chain",
           "cf2", "cf3", "ckf3", "dckf3", "cfn", "position", "ckf3_printed", "dckf3_printed",
           "eq32_denominator", "structure", "STRUCTURES"]
