"""Runtime filters that consume a GainTable: numpy only (no sympy; scipy only in the batch path)."""

from .filter import Runtime, wrap

__all__ = ["Runtime", "wrap"]
