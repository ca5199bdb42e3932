"""One exception family for cfdesign.

Every error a user can cause (a bad spec, an unknown structure, a gain that is missing,
a Riccati problem with no stabilising solution) is a :class:`CfdesignError`.  The CLI
catches this family and prints its message on one line; anything else is a bug and keeps
its traceback.
"""

from __future__ import annotations

__all__ = [
    "CfdesignError",
    "SpecError",
    "StructureError",
    "GainError",
    "ProofError",
    "RiccatiError",
    "NotStabilisableError",
    "NotDetectableError",
    "NoStabilisingSolutionError",
    "AccuracyError",
    "GainTableError",
    "TableMismatchError",
    "InputError",
    "AttitudeInputError",
    "DataError",
    "OutputError",
    "InternalError",
]


class CfdesignError(Exception):
    """Base class of every error cfdesign raises on purpose."""

    #: exit status the CLI uses for this kind of error
    exit_code = 2


class SpecError(CfdesignError, ValueError):
    """A specification (sensor, filter, design file) is invalid; the message names the field."""


class StructureError(CfdesignError, ValueError):
    """An observer structure is malformed (matrix shapes, sensor ports, unknown structure name)."""


class GainError(CfdesignError, ValueError):
    """Gains or parameters given for a filter are missing, unknown or not numbers."""


class TableMismatchError(GainError):
    """A gain table (or design spec) given to a filter does not fit it: its structure, gain form,
    sample time or sensor rates differ from what the filter runs; the message names the mismatch."""


class ProofError(CfdesignError):
    """A complementarity proof could not be carried out (not: the proof failed)."""


class RiccatiError(CfdesignError, ValueError):
    """A Riccati equation is ill-posed or its solution could not be trusted."""


class NotStabilisableError(RiccatiError):
    """The pair (A, B) has an unstable mode that the input cannot reach (PBH test)."""


class NotDetectableError(RiccatiError):
    """The pair (A, C) has an unstable mode that the outputs cannot see (PBH test)."""


class NoStabilisingSolutionError(RiccatiError):
    """The Riccati equation has no stabilising solution (e.g. a mode on the stability boundary)."""


class AccuracyError(RiccatiError):
    """A solution was computed but failed the residual or stability check after refinement."""


class GainTableError(CfdesignError):
    """A gain table file cannot be read, is malformed, or fails its schema."""


class InputError(CfdesignError, ValueError):
    """Data or arguments given to a filter or a simulation are invalid: an array of the wrong
    shape or with unusable values, a rate or duration that does not fit; the message names the
    argument.  (Design files and specifications raise :class:`SpecError`.)"""


class AttitudeInputError(InputError):
    """Bad input to an attitude filter (array shapes, sample rate, noise figures); names the argument."""


class DataError(InputError):
    """A sensor log cannot be used (a missing column, text in a number column, bad times);
    the message names the file, the row or the column."""


class OutputError(CfdesignError):
    """An output file cannot be written; no existing file was replaced."""


class InternalError(CfdesignError):
    """A bug: cfdesign reached a state it should not.  The CLI asks for a report (exit 3)."""

    exit_code = 3
