"""GainTable: the designed filter as data - model, gains per phase, predicted error, provenance.

A gain table holds everything needed to run the filter and to re-check it: the discrete (or
continuous) model ``F, B, H``, the gain ``K[k]`` of every phase of the period in the named
gain form, the predicted steady-state covariances, the sensors and how they enter, and where
it came from (spec hash, toolkit version, solver residuals).  JSON floats are written with
``repr`` precision, so a save/load round trip is exact.

Gain forms (DESIGN.md conventions):

* ``predictor``: ``x[k+1] = F x[k] + B u[k] + K[k] (y[k] - H x[k])``, estimate ``x[k]``;
* ``filter``: ``x+[k] = x-[k] + K[k] (y[k] - H x-[k])``, ``x-[k+1] = F x+[k] + B u[k]``,
  estimate ``x+[k]``;
* ``continuous``: ``x' = F x + B u + K (y - H x)``.

At a phase where a measurement sensor has no reading, its column of ``K[k]`` is exactly zero.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .errors import CfdesignError, GainTableError

__all__ = ["GainTable", "load_gains", "validate", "schema", "FORMAT_VERSION"]

#: version of the JSON layout written by :meth:`GainTable.save`
FORMAT_VERSION = 1
SCHEMA_PATH = Path(__file__).resolve().parent / "schemas" / f"gaintable-{FORMAT_VERSION}.schema.json"


def schema() -> dict:
    """The JSON Schema (draft 2020-12) of the gain table format."""
    return json.loads(SCHEMA_PATH.read_text())


def validate(data: dict, source: str = "gain table"):
    """Check a parsed gain table against the schema and its shape rules; raise GainTableError.

    The schema fixes the fields and types; the shapes (``F`` n x n, ``B`` n x p, ``H`` m x n,
    ``K[k]`` n x m, one ``measured`` list per phase) are checked here, naming the field.
    """
    import jsonschema

    if isinstance(data, dict) and data.get("format_version") not in (None, FORMAT_VERSION):
        raise GainTableError(f"{source}: unsupported format_version {data.get('format_version')!r} "
                             f"(this cfdesign reads {FORMAT_VERSION})")
    try:
        jsonschema.validate(data, schema())
    except jsonschema.ValidationError as exc:
        where = "/".join(map(str, exc.absolute_path)) or "(top level)"
        raise GainTableError(f"{source}: schema violation at {where}: {exc.message}") from None
    _check_shapes(data, source)


def _check_shapes(d, source):
    n = len(d["F"])
    m, p = len(d["H"]), len(d["B"][0]) if d["B"] else 0
    expect = {"F": (n, n), "B": (n, p), "H": (m, n), "Q": (n, n), "R": (m, m)}
    for key, shape in expect.items():
        _shape_of(d[key], shape, f"{source}: {key}")
    for key, shape in (("K", (n, m)), ("P", (n, n)), ("P_filtered", (n, n))):
        if len(d[key]) != len(d["K"]):
            raise GainTableError(f"{source}: {key} has {len(d[key])} phases, K has {len(d['K'])}")
        for k, M in enumerate(d[key]):
            _shape_of(M, shape, f"{source}: {key}[{k}]")
    if len(d["measured"]) != len(d["K"]):
        raise GainTableError(f"{source}: measured has {len(d['measured'])} phases, K has {len(d['K'])}")
    roles = {"input": p, "measurement": m}
    for role, count in roles.items():
        idx = sorted(s["index"] for s in d["sensors"] if s["role"] == role)
        if idx != list(range(count)):
            raise GainTableError(f"{source}: sensors: {role} indices {idx} do not match the {count} "
                                 f"{'columns of B' if role == 'input' else 'rows of H'}")


def _shape_of(M, shape, what):
    rows = len(M)
    cols = {len(r) for r in M}
    if rows != shape[0] or (rows and cols != {shape[1]}):
        got = f"{rows}x{'/'.join(map(str, sorted(cols))) or 0}"
        raise GainTableError(f"{what} must be {shape[0]}x{shape[1]}, got {got}")


@dataclass(frozen=True)
class GainTable:
    """A designed filter: model, per-phase gains and predicted errors.

    Attributes
    ----------
    name, structure : str
        Design name and structure (``dckf3``, ``position``, ...); ``options`` holds the
        structure options (``order``, ``bands``, ``discrete``).
    domain : {'s', 'z'}
    sample_time_s : float or None
        Base sample time (s); None for continuous filters.
    gain_form : {'predictor', 'filter', 'continuous'}
    sensors : list of dict
        ``name``, ``role`` (input/measurement), ``index`` (column of B / row of H),
        ``order`` (0 angle/position, 1 rate, 2 acceleration), ``rate_hz``.
    F, B, H : ndarray
        Model matrices (the discrete model for ``domain = 'z'``).
    K : list of ndarray
        Gain per phase, shape (n, m) each; ``len(K)`` is the period.
    P : list of ndarray
        Predicted (a-priori) steady-state error covariance per phase.
    P_filtered : list of ndarray
        A-posteriori covariance per phase (equal to ``P`` where nothing is measured).
    measured : list of list of str
        Measurement sensors with a reading at each phase.
    gains : dict
        ``{gain symbol: value}`` for single-rate tables (e.g. ``k11``); empty when periodic.
    wrap_angle : bool
        The quantity is an angle on a circle (a heading): runtimes wrap the innovations of
        angle sensors and the estimate to (-pi, pi].
    Q, R : ndarray
        Process and measurement noise covariances used (per sample for discrete tables).
    provenance : dict
        ``spec_sha256``, ``cfdesign_version``, ``created_utc``, ``solver`` details.
    checks : dict
        ``complementary`` (exact proof verdict), ``poles`` or ``monodromy_multipliers``
        (as ``[re, im]`` pairs) and ``stable``.
    """

    name: str
    structure: str
    domain: str
    sample_time_s: float | None
    gain_form: str
    sensors: list
    F: np.ndarray
    B: np.ndarray
    H: np.ndarray
    K: list
    P: list
    P_filtered: list
    measured: list
    Q: np.ndarray
    R: np.ndarray
    gains: dict = field(default_factory=dict)
    wrap_angle: bool = False
    options: dict = field(default_factory=dict)
    provenance: dict = field(default_factory=dict)
    checks: dict = field(default_factory=dict)

    @property
    def period(self) -> int:
        return len(self.K)

    @property
    def predicted_std(self) -> float:
        """Predicted steady-state standard deviation of the estimate (first state), worst phase.

        Uses the covariance of the estimate the gain form outputs: a-priori for predictor
        tables, a-posteriori for filter tables.
        """
        covs = self.P_filtered if self.gain_form == "filter" else self.P
        return float(np.sqrt(max(c[0, 0] for c in covs)))

    def phase_model(self, phase: int) -> tuple:
        """``(F, B, H_k, K_k)`` of one phase: ``H_k`` keeps the rows of the sensors measured at
        that phase and ``K_k`` their gain columns (the per-phase view of a multirate table)."""
        k = phase % self.period
        names = [s["name"] for s in sorted(self.sensors, key=lambda s: s["index"]) if s["role"] == "measurement"]
        rows = [i for i, name in enumerate(names) if name in self.measured[k]]
        return self.F, self.B, self.H[rows, :], self.K[k][:, rows]

    def sensor_names(self, role: str | None = None) -> list:
        return [s["name"] for s in self.sensors if role is None or s["role"] == role]

    # ------------------------------------------------------------------ JSON
    def to_dict(self) -> dict:
        d = asdict(self)
        for key in ("F", "B", "H", "Q", "R"):
            d[key] = np.asarray(d[key]).tolist()
        for key in ("K", "P", "P_filtered"):
            d[key] = [np.asarray(m).tolist() for m in d[key]]
        return {"format_version": FORMAT_VERSION, **d}

    def save(self, path) -> Path:
        """Write the table as JSON (full float precision); returns the path."""
        path = Path(path)
        text = json.dumps(self.to_dict(), indent=1, allow_nan=False)
        try:
            path.write_text(text + "\n")
        except OSError as exc:
            raise CfdesignError(f"cannot write {path}: {exc.strerror or exc}") from None
        return path

    @classmethod
    def from_dict(cls, d: dict, source: str = "gain table") -> GainTable:
        """Build a table from its JSON form after validating it (:func:`validate`)."""
        validate(d, source)
        try:
            kw = {k: d[k] for k in cls.__dataclass_fields__ if k in d}
            for key in ("F", "B", "H", "Q", "R"):
                kw[key] = np.array(d[key], dtype=float)
            for key in ("K", "P", "P_filtered"):
                kw[key] = [np.array(m, dtype=float).reshape(_shape(key, d)) for m in d[key]]
            return cls(**kw)
        except (KeyError, TypeError, ValueError) as exc:
            raise GainTableError(f"{source}: malformed gain table: {exc}") from None


def _shape(key, d):
    n = len(d["F"])
    return (n, len(d["H"])) if key == "K" else (n, n)


def load_gains(path) -> GainTable:
    """Read a gain table written by :meth:`GainTable.save`."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
    except OSError as exc:
        raise GainTableError(f"cannot read gain table {path}: {exc.strerror or exc}") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise GainTableError(f"{path}: not valid JSON: {exc}") from None
    return GainTable.from_dict(data, str(path))
