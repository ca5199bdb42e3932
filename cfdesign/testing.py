"""Helpers for users' own test suites: keep the gains on the robot true to the design.

    from cfdesign.testing import assert_complementary

    def test_robot_gains():
        assert_complementary("firmware/gains.json", spec="design/heading.toml")
"""

from __future__ import annotations

__all__ = ["assert_complementary"]


def assert_complementary(table, spec=None, rtol: float = 1e-9):
    """Assert that a gain table is still what its design says.

    Runs :func:`cfdesign.verify.verify_table`: the bands sum to one, the filter is stable,
    and (with ``spec``) re-designing gives the same gains.  For users' own test suites.

    Parameters
    ----------
    table : GainTable or str or Path
        The table, or its JSON file.
    spec : FilterSpec or str or Path, optional
        The design, or its TOML file.
    rtol : float
        Relative tolerance of the gain comparison.

    Raises
    ------
    AssertionError
        One line per failed check.
    GainTableError
        The table file cannot be read.
    SpecError
        The design file cannot be read.

    Examples
    --------
    >>> import cfdesign
    >>> from cfdesign.testing import assert_complementary
    >>> spec = cfdesign.load_spec(cfdesign.example_path("position"))
    >>> assert_complementary(cfdesign.design(spec), spec=spec)
    """
    from .gains import GainTable, load_gains
    from .spec import FilterSpec, load_spec
    from .verify import verify_table

    table = table if isinstance(table, GainTable) else load_gains(table)
    if spec is not None and not isinstance(spec, FilterSpec):
        spec = load_spec(spec)
    failed = [c.line() for c in verify_table(table, spec, rtol) if not c.ok]
    if failed:
        raise AssertionError(f"{table.name}: " + "; ".join(failed))
