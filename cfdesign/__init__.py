"""cfdesign: design, prove and run complementary filters for robot and UAV sensor fusion.

The symbolic engine (:mod:`cfdesign.symbolic`) turns a linear observer of a kinematic chain
(F, B, H, K) into the band transfer function of every sensor and proves exactly that the
bands sum to one.  The named filters of the source papers are small constructors on it.
:func:`~cfdesign.designer.design` turns a sensor specification into optimal gains (CARE, DARE, periodic DARE)
and a :class:`~cfdesign.gains.GainTable`; :mod:`cfdesign.runtime` runs one.

The public names below are loaded on first use, so that ``import cfdesign.runtime`` (the
part that runs on a robot) never imports sympy.
"""

from importlib import import_module

from .errors import CfdesignError, GainError, ProofError, RiccatiError, SpecError, StructureError

#: The version of cfdesign
__version__ = "0.1.0"

_LAZY = {
    "cfdesign.symbolic": ["Observer", "Sensor", "Proof", "prove", "structure", "STRUCTURES", "cf2", "cf3", "ckf3",
                          "dckf3", "cfn", "position", "ckf3_printed", "dckf3_printed", "eq32_denominator"],
    "cfdesign.analysis": ["transfer_functions", "frequency_response", "FrequencyResponse"],
    "cfdesign.plot": ["bode_plot"],
    "cfdesign.spec": ["FilterSpec", "SensorSpec", "load_spec", "parse_spec", "example_path"],
    "cfdesign.gains": ["GainTable", "load_gains"],
    "cfdesign.designer": ["design", "multirate_schedule"],
    "cfdesign.runtime": ["Runtime"],
    "cfdesign.allan": ["identify_noise", "NoiseFit"],
}
_WHERE = {name: module for module, names in _LAZY.items() for name in names}
_MODULES = {"riccati", "runtime", "symbolic", "analysis", "plot", "noise", "spec", "gains", "designer", "testing",
            "sim", "reproduce", "verify", "codegen", "export", "nav", "allan"}

__all__ = ["__version__", "CfdesignError", "SpecError", "StructureError", "GainError", "ProofError",
           "RiccatiError", *_WHERE, *sorted(_MODULES)]


def __getattr__(name):
    if name in _WHERE:
        value = getattr(import_module(_WHERE[name]), name)
    elif name in _MODULES:
        value = import_module(f"cfdesign.{name}")
    else:
        raise AttributeError(f"module 'cfdesign' has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(__all__)
