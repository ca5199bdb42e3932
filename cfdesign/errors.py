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


#: the extra of pyproject.toml that installs each optional package cfdesign imports (by the top-level
#: module's name); every import of one goes through :func:`require_extra` (tests/test_packaging.py)
EXTRAS = {"pandas": "logs", "pyarrow": "logs", "dask": "fleet", "distributed": "fleet"}


def install_hint(module: str):
    """The install command of a missing module's extra, or None when no extra installs it.

    Parameters
    ----------
    module : str
        A module name, dotted or not (``"pyarrow.parquet"``).

    Returns
    -------
    str or None
        ``pip install "cfdesign[EXTRA]"``, or None for a module of no extra.
    """
    extra = EXTRAS.get(module.split(".")[0])
    return f'pip install "cfdesign[{extra}]"' if extra else None


def require_extra(module: str, needed_for: str):
    """Import an optional package's module, or raise one line naming the extra that installs it.

    Parameters
    ----------
    module : str
        The module, dotted or not (``"pyarrow.parquet"``); its top-level name is a key of
        :data:`EXTRAS`.
    needed_for : str
        What needs it, the start of the message (``"reading logs needs pandas"``).

    Returns
    -------
    module
        The imported module.

    Raises
    ------
    CfdesignError
        The module cannot be imported: ``"{needed_for}: pip install "cfdesign[EXTRA]""``.
    """
    from importlib import import_module

    hint = install_hint(module)
    if hint is None:  # a programming error: every optional package has its extra
        raise InternalError(f"{module} is not an optional package of cfdesign (cfdesign.errors.EXTRAS)")
    try:
        return import_module(module)
    except ImportError:
        raise CfdesignError(f"{needed_for}: {hint}") from None
