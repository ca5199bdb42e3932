"""Input checks shared by the two attitude filters, and their initial attitude.

Every check raises :class:`~cfdesign.errors.AttitudeInputError` naming the argument.
Frames as :mod:`cfdesign.rotations` (ENU, quaternions ``[w, x, y, z]`` body -> ENU).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .. import rotations as rot
from ..errors import AttitudeInputError
from .mps import mps_quaternion

__all__ = ["number", "positive", "rate", "rows", "vectors", "finite_vector", "held_rows", "imu_inputs", "usable_rows",
           "initial_quaternion"]

#: fastest and slowest sample rates the navigation filters accept (Hz): their tables and process
#: noise are computed per sample
MAX_RATE_HZ = 1e6
MIN_RATE_HZ = 1e-3


#: the column names' last letters that give the axis order of a DataFrame of vectors or quaternions
AXES = {3: "xyz", 4: "wxyz"}


def number(name, value, error=AttitudeInputError) -> float:
    """A real number as a float: a Python or numpy real, or a 0-d array of one; not a bool, not text.

    Parameters
    ----------
    name : str
        The argument's name, as the error message shows it.
    value : float
        The value (its unit is the caller's).
    error : type
        The :class:`~cfdesign.errors.CfdesignError` subclass to raise (an
        :class:`~cfdesign.errors.InputError` by default; a design file's ``SpecError``).

    Returns
    -------
    float
        ``float(value)`` (NaN and infinities are returned: the caller bounds the value).

    Raises
    ------
    InputError
        ``value`` is a bool (``True`` read as 1), text (``"100"``: the design files refuse quoted
        numbers too), None, complex, an array of one value or more, or an integer beyond a double.

    Examples
    --------
    >>> from cfdesign.nav.attitude_inputs import number
    >>> number("rate_hz", np.float32(100))
    100.0
    >>> number("rate_hz", True)
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: rate_hz must be a number, got True
    """
    v = value.item() if isinstance(value, np.ndarray) and value.shape == () else value
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
        raise error(f"{name} must be a number, got {value!r}")
    try:
        return float(v)
    except OverflowError:
        raise error(f"{name} must be a number of a double's range, got {str(value)[:20]}...") from None


def positive(name, value, allow_zero=False, error=AttitudeInputError) -> float:
    """Check that a scalar is a finite positive (or non-negative) number and return it as a float.

    Parameters
    ----------
    name : str
        The argument's name, as the error message shows it (``rate_hz``, ``gyro_noise_std``).
    value : float
        The value to check (a real number: :func:`number`); its unit is the caller's (Hz, rad/s
        per sample, ...).
    allow_zero : bool
        Accept zero as well (non-negative instead of positive).
    error : type
        The :class:`~cfdesign.errors.CfdesignError` subclass to raise (an
        :class:`~cfdesign.errors.InputError` by default; a design file's ``SpecError``).

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    InputError
        ``value`` is not a number (:func:`number`: a bool or text is not one), is NaN or infinite,
        is negative, or is zero while ``allow_zero`` is False; the message names ``name``.

    Examples
    --------
    >>> from cfdesign.nav.attitude_inputs import positive
    >>> positive("rate_hz", 100)
    100.0
    >>> positive("rate_hz", 0)
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: rate_hz must be a finite positive number, got 0.0
    >>> positive("declination", 0, allow_zero=True)
    0.0
    """
    value = number(name, value, error)
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        raise error(f"{name} must be a finite {'non-negative' if allow_zero else 'positive'} "
                                 f"number, got {value!r}")
    return value


def rate(value, name="rate_hz", error=AttitudeInputError) -> float:
    """Check a sample rate before anything is designed or allocated and return it as a float.

    Parameters
    ----------
    value : float
        The rate (Hz).
    name : str
        The argument's name, as the error message shows it.
    error : type
        The :class:`~cfdesign.errors.CfdesignError` subclass to raise (an
        :class:`~cfdesign.errors.InputError` by default; a design file's ``SpecError``).

    Returns
    -------
    float
        ``float(value)``.

    Raises
    ------
    InputError
        ``value`` is not a number (:func:`number`: a bool or text is not one) or is outside
        ``[MIN_RATE_HZ, MAX_RATE_HZ]`` (1e-3 to 1e6 Hz; NaN too); the message names ``name``.

    Examples
    --------
    >>> from cfdesign.nav.attitude_inputs import rate
    >>> rate(100)
    100.0
    >>> rate(0.0)
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: rate_hz must be a number in [0.001, 1e+06] Hz, got 0.0
    """
    out = number(name, value, error)
    if not MIN_RATE_HZ <= out <= MAX_RATE_HZ:  # NaN too
        raise error(f"{name} must be a number in [{MIN_RATE_HZ:g}, {MAX_RATE_HZ:g}] Hz, got {value!r}")
    return out


def rows(name, value, width=None, n=None, error=AttitudeInputError) -> np.ndarray:
    """Check that a value is an array of real numbers, one row (or one number) per sample.

    Parameters
    ----------
    name : str
        The argument's name, as the error message shows it.
    value : array_like (N,) or (N, width)
        The readings.  A DataFrame is read by position; one whose column names end in the axis
        letters (``x, y, z``; ``w, x, y, z`` for quaternions; any case: ``gyro_X``) in another order
        is refused.
    width : int, optional
        Columns per row; None: one number per sample, shape (N,).
    n : int, optional
        The number of rows required; any number when None.
    error : type
        The :class:`~cfdesign.errors.CfdesignError` subclass to raise (an
        :class:`~cfdesign.errors.InputError` by default; a design file's ``SpecError``).

    Returns
    -------
    ndarray (N,) or (N, width)
        ``value`` as a float array (not copied when it already is one).  Non-finite entries are
        kept.

    Raises
    ------
    InputError
        ``value`` is not an array of real numbers (text, None and complex values are refused as
        ``cfdesign.runtime.filter.real_array`` refuses them), has another shape, or a number of
        rows other than ``n``, or is a DataFrame whose columns are named by the axis letters in
        another order, or whose rows are named by them and columns are not (one axis per row:
        transposed); the message names ``name``.

    Examples
    --------
    >>> from cfdesign.nav.attitude_inputs import rows
    >>> rows("odometry_speed", [1, 2, 3]).tolist()
    [1.0, 2.0, 3.0]
    >>> rows("gps_xy", [[0.0, 1.0]] * 2, width=3)
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: gps_xy must have shape (N, 3), got (2, 2)
    """
    from ..errors import CfdesignError
    from ..runtime.filter import real_array

    shape = "(N,)" if width is None else f"(N, {width})"
    value = _by_axis(name, value, width, error)
    try:
        arr = real_array(value, name)
    except CfdesignError as exc:
        raise error(f"{exc}: a numeric array of shape {shape} is needed") from None
    if arr.ndim != (1 if width is None else 2) or (width is not None and arr.shape[1] != width):
        raise error(f"{name} must have shape {shape}, got {arr.shape}")
    if n is not None and len(arr) != n:
        raise error(f"{name} has {len(arr)} rows but {n} are needed")
    return arr


def _axis_letters(labels, width) -> list | None:
    """The axis order ``labels`` give (indices into them, in ``AXES[width]`` order), or None when
    their last letters are not the axis letters."""
    letters = [str(label).strip().lower()[-1:] for label in labels]
    if width not in AXES or len(letters) != width or sorted(letters) != sorted(AXES[width]):
        return None
    return [letters.index(a) for a in AXES[width]]


def _by_axis(name, value, width, error):
    """A DataFrame as it is, unless its column names end in the axis letters in another order
    (``gz, gx, gy``; ``qx, qy, qz, qw``: the order of scipy's quaternions): refused, as neither the
    names (read by position, they mislabel the axes) nor the position (a remap such as
    ``concat([g.gy, -g.gx, g.gz])`` keeps the sensor's names) can be taken as meant; and a DataFrame
    of one axis per row (transposed: its index names the axes) refused."""
    columns, index = getattr(value, "columns", None), getattr(value, "index", None)
    if columns is None or index is None or width is None:
        return value
    order = _axis_letters(columns, width)
    if order is not None and order != list(range(width)):
        axes = ", ".join(AXES[width])
        raise error(f"{name}: the DataFrame's columns are named {list(columns)}, not in the order {axes}: select "
                    f"them in that order ({name}[[{', '.join(repr(columns[i]) for i in order)}]]), or pass "
                    f"{name}.to_numpy() to take them as they stand")
    if order is None and _axis_letters(index, width) is not None:
        raise error(f"{name}: the DataFrame's rows are named {list(index)}: one axis per row; samples must "
                    f"be rows, axes columns (shape (N, {width})): pass {name}.T")
    return value


def finite_vector(name, value, size=3, error=AttitudeInputError) -> np.ndarray:
    """Check an initial state (a position, a velocity, a pose): ``size`` finite real numbers.

    Parameters
    ----------
    name : str
        The argument's name, as the error message shows it.
    value : array_like (size,)
        The numbers.
    size : int
        How many.
    error : type
        The :class:`~cfdesign.errors.CfdesignError` subclass to raise (an
        :class:`~cfdesign.errors.InputError` by default; a design file's ``SpecError``).

    Returns
    -------
    ndarray (size,)
        A new float array.

    Raises
    ------
    InputError
        ``value`` is not ``size`` real numbers, or one is not finite or beyond
        :data:`~cfdesign.runtime.filter.READING_LIMIT`; the message names ``name``.

    Examples
    --------
    >>> from cfdesign.nav.attitude_inputs import finite_vector
    >>> finite_vector("initial_position", [1, 2, 3]).tolist()
    [1.0, 2.0, 3.0]
    >>> finite_vector("initial_position", [1.0, float("nan"), 3.0])
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: initial_position must be 3 finite numbers, got [1.0, nan, 3.0]
    """
    from ..runtime.filter import usable

    try:
        v = rows(name, value, error=error)
    except error:
        v = None
    if v is None or v.shape != (size,) or not usable(v).all():
        raise error(f"{name} must be {size} finite numbers, got {' '.join(repr(value).split())[:80]}")
    return v.copy()


def held_rows(values, limit=None, bad=None) -> tuple:
    """Rows that are not usable readings replaced by the last usable one: the missing readings of
    an input every sample needs (a rate, a specific force, a distance).

    A row is usable when every entry is finite and within
    :data:`~cfdesign.runtime.filter.READING_LIMIT` (beyond it a reading is not physical and would
    overflow the state) and its norm is within ``limit`` (the sensor's range); rows before the
    first usable one take that one, and zero when there is none.

    Parameters
    ----------
    values : ndarray (N,) or (N, k)
        Readings, one row (or number) per sample.
    limit : float, optional
        The largest norm of a usable row (the sensor's range, in its unit).
    bad : ndarray (N,) of bool, optional
        Rows not to use besides those (a zero quaternion).

    Returns
    -------
    held : ndarray, same shape as ``values``
        A new array, every row usable.
    missing : int
        How many rows were replaced.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.nav.attitude_inputs import held_rows
    >>> held, missing = held_rows(np.array([np.nan, 1.0, np.inf, 2e12, 3.0]))
    >>> held.tolist(), missing
    ([1.0, 1.0, 1.0, 1.0, 3.0], 3)
    """
    from ..runtime.filter import held, usable

    a = values[:, None] if values.ndim == 1 else values
    bad = ~usable(a).all(axis=1) | (False if bad is None else bad)
    if limit is not None:
        bad |= ~(np.linalg.norm(np.where(bad[:, None], 0.0, a), axis=1) <= limit)
    good = np.flatnonzero(~bad)
    first = a[good[0]] if len(good) else np.zeros(a.shape[1])
    out = held(a, np.repeat(bad[:, None], a.shape[1], axis=1), first)
    return out.reshape(values.shape), int(bad.sum())


def vectors(name, value, n=None, allow_none=False):
    """Check that a value is an array of 3-vectors, one row per sample, and return it as floats.

    Parameters
    ----------
    name : str
        The argument's name, as the error message shows it (``acc``, ``mag``).
    value : array_like (N, 3) or None
        Body-frame readings (rad/s, m/s², a field, m/s: the caller's unit), one row per sample.
    n : int, optional
        The number of rows required (the length of the gyro log); any number when None.
    allow_none : bool
        Return None for ``value=None`` (an optional sensor) instead of raising.

    Returns
    -------
    ndarray (N, 3) or None
        ``value`` as a float array (not copied when it already is one); None when ``value`` is
        None and ``allow_none`` is True.  Non-finite entries are kept.

    Raises
    ------
    AttitudeInputError
        ``value`` is not an array of real numbers (text, None, complex values are refused, as
        ``cfdesign.runtime.filter.real_array`` refuses them), is not two-dimensional with
        three columns (None included when not allowed), or has a number of rows other than
        ``n``; the message names ``name``.

    Examples
    --------
    >>> from cfdesign.nav.attitude_inputs import vectors
    >>> vectors("acc", [[0, 0, 9.81], [0, 0, 9.80]]).shape
    (2, 3)
    >>> vectors("mag", None, 2, allow_none=True) is None
    True
    >>> vectors("acc", [0, 0, 9.81])
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: acc must have shape (N, 3), got (3,)
    """
    if value is None and allow_none:
        return None
    arr = rows(name, value, 3)
    if n is not None and len(arr) != n:
        raise AttitudeInputError(f"{name} has {len(arr)} rows but gyr has {n}")
    return arr


def imu_inputs(gyr, acc, mag, velocity_body=None):
    """Check the logs of an attitude filter: equal-length (N, 3) arrays with at least one sample.

    Only shapes are checked: non-finite or zero rows pass (the filters treat them as missing
    readings, see :func:`usable_rows`).

    Parameters
    ----------
    gyr : array_like (N, 3)
        Body rate, rad/s, body (sensor) frame; sets N, which must be at least 1.
    acc : array_like (N, 3)
        Specific force, m/s², body frame (points up at rest).
    mag : array_like (N, 3) or None
        Magnetic field, body frame, any consistent unit (Gauss, uT or normalised: only its
        direction is used); None without a magnetometer.
    velocity_body : array_like (N, 3), optional
        Velocity in the body frame, m/s (for the centripetal compensation of the
        accelerometer); None without.

    Returns
    -------
    tuple
        ``(gyr, acc, mag, velocity_body)`` as float arrays of shape (N, 3), ``mag`` and
        ``velocity_body`` None when not given.

    Raises
    ------
    AttitudeInputError
        ``gyr`` is empty, an argument is not numeric or not of shape (N, 3), or its row count
        differs from ``gyr``'s; the message names the argument.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.nav.attitude_inputs import imu_inputs
    >>> gyr, acc, mag, vel = imu_inputs(np.zeros((4, 3)), [[0, 0, 9.81]] * 4, None)
    >>> acc.shape, mag, vel
    ((4, 3), None, None)
    >>> imu_inputs(np.zeros((4, 3)), np.zeros((3, 3)), None)
    Traceback (most recent call last):
    ...
    cfdesign.errors.AttitudeInputError: acc has 3 rows but gyr has 4
    """
    gyr = vectors("gyr", gyr)
    if len(gyr) == 0:
        raise AttitudeInputError("gyr is empty: need at least one sample")
    acc = vectors("acc", acc, len(gyr))
    mag = vectors("mag", mag, len(gyr), allow_none=True)
    vel = vectors("velocity_body", velocity_body, len(gyr), allow_none=True)
    return gyr, acc, mag, vel


def usable_rows(vectors_):
    """Mark the readings that cannot correct the attitude: rows not finite, beyond
    :data:`~cfdesign.runtime.filter.READING_LIMIT` or all zero become NaN.

    A filter skips the correction of a NaN row (a missing accelerometer or magnetometer sample).

    Parameters
    ----------
    vectors_ : ndarray (N, 3) or None
        Readings in the body frame (specific force in m/s², or a field in any unit), as
        returned by :func:`vectors`.

    Returns
    -------
    ndarray (N, 3) or None
        A new array: the usable rows unchanged, the others all NaN; None when ``vectors_`` is
        None.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.nav.attitude_inputs import usable_rows
    >>> usable_rows(np.array([[0.0, 0.0, 9.81], [0.0, 0.0, 0.0], [np.nan, 0.0, 9.81]]))
    array([[0.  , 0.  , 9.81],
           [ nan,  nan,  nan],
           [ nan,  nan,  nan]])
    >>> usable_rows(None) is None
    True
    """
    if vectors_ is None:
        return None
    from ..runtime.filter import usable

    bad = ~usable(vectors_).all(axis=1) | ~(np.abs(vectors_).sum(axis=1) > 0)
    return np.where(bad[:, None], np.nan, vectors_)


def initial_quaternion(acc, mag, declination_rad, initial):
    """The attitude a filter starts from: the given quaternion, else the MPS of the first usable sample.

    Without ``initial``, the Magneto-Pendular Sensor (:func:`~cfdesign.nav.mps.mps_quaternion`,
    Vasconcelos et al.) of one sample gives it: the first sample whose ``acc`` and ``mag`` rows
    are both finite or, when there is none (or no magnetometer), the first sample with a finite
    ``acc`` row, heading zero.  Without any finite ``acc`` row, the identity.

    Parameters
    ----------
    acc : ndarray (N, 3)
        Specific force, m/s², body frame, unusable rows NaN (:func:`usable_rows`).
    mag : ndarray (N, 3) or None
        Magnetic field, body frame, any consistent unit (Gauss, uT or normalised), unusable
        rows NaN; None without a magnetometer (heading zero).
    declination_rad : float
        Magnetic declination (rad), positive east.
    initial : array_like (4,) or None
        A quaternion ``[w, x, y, z]`` (body -> ENU), any non-zero norm; None: from the samples.

    Returns
    -------
    ndarray (4,)
        Unit quaternion ``[w, x, y, z]``, body -> ENU.

    Raises
    ------
    AttitudeInputError
        ``initial`` is given but is not four finite numbers or is zero.

    Examples
    --------
    >>> import numpy as np
    >>> from cfdesign.nav.attitude_inputs import initial_quaternion
    >>> initial_quaternion(None, None, 0.0, [2.0, 0.0, 0.0, 0.0])
    array([1., 0., 0., 0.])
    >>> acc = np.array([[np.nan, np.nan, np.nan], [0.0, 0.0, 9.81]])
    >>> initial_quaternion(acc, np.array([[0.0, 0.2, -0.4]] * 2), 0.0, None).round(6).tolist()
    [1.0, 0.0, 0.0, 0.0]
    """
    if initial is not None:
        q0 = np.asarray(initial, dtype=float)
        if q0.shape != (4,) or not np.isfinite(q0).all() or np.linalg.norm(q0) == 0:
            raise AttitudeInputError(f"initial must be a finite non-zero quaternion [w, x, y, z], got {initial!r}")
        return rot.normalize(q0)
    rows = np.flatnonzero(np.isfinite(acc).all(axis=1))
    if len(rows) == 0:
        return np.array([1.0, 0.0, 0.0, 0.0])
    k = rows[0]
    if mag is not None:
        good = rows[np.isfinite(mag[rows]).all(axis=1)]
        k = good[0] if len(good) else k
    return mps_quaternion(acc[k], None if mag is None else mag[k], declination_rad=declination_rad)
