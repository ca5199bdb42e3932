"""Helpers for users' own test suites: keep the gains on the robot true to the design.

    from cfdesign.testing import assert_complementary

    def test_robot_gains():
        assert_complementary("firmware/gains.json", spec="design/heading.toml")
"""

from __future__ import annotations

__all__ = ["assert_complementary"]


def assert_complementary(table, spec=None, rtol: float = 1e-9):
    """Assert that a gain table's bands sum to one, its filter is stable, and (with ``spec``)
    that re-designing gives the same gains.  ``table`` and ``spec`` may be objects or paths.

    Raises ``AssertionError`` with one line per failed check.
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
