"""``estimate_attitude``: the whole-array call of :class:`~cfdesign.nav.AttitudeFilter`.

The attitude filter for real IMUs (gyro, accelerometer, optional magnetometer) is
:class:`cfdesign.nav.AttitudeFilter` (:mod:`cfdesign.nav.attitude_filter`: designed
velocity, tilt, heading and zero-rotation channels, rest detection, magnetic and acceleration
disturbances).  :func:`estimate_attitude` builds one and runs it over arrays; its keyword
arguments are those of earlier versions plus any :class:`~cfdesign.nav.AttitudeParams` field.

Frames: attitude of the body (sensor) frame relative to **ENU** (x east, y north, z up);
quaternions ``[w, x, y, z]`` map body to ENU.
"""

from __future__ import annotations

import warnings

from ..errors import AttitudeInputError
from .attitude_filter import AttitudeFilter, AttitudeParams, _rate

__all__ = ["estimate_attitude", "DEFAULT_NOISE"]

#: the noise densities :func:`estimate_attitude` takes by name, with their defaults (AttitudeParams)
DEFAULT_NOISE = {name: getattr(AttitudeParams(), name) for name in
                 ("gyro_noise_density", "gyro_bias_density", "tilt_noise_density", "heading_noise_density")}


def estimate_attitude(gyr, acc, mag, rate_hz, *, gyro_noise_density=None, gyro_bias_density=None,
                      tilt_noise_density=None, heading_noise_density=None, declination_rad=0.0,
                      gyro_bias_std0=0.0175, initial=None, correction_rate_hz=None, return_bias=False, tables=None,
                      **params):
    """Attitude quaternions of the sensor frame relative to **ENU** from a gyro, accelerometer and magnetometer.

    ``AttitudeFilter(rate_hz, magnetometer=mag is not None, ...).run(gyr, acc, mag)``: see
    :class:`~cfdesign.nav.AttitudeFilter` for the filter and :class:`~cfdesign.nav.AttitudeParams`
    for every parameter (given here as keyword arguments).

    Parameters
    ----------
    gyr : array_like (N, 3)
        Body rate, rad/s, body frame.
    acc : array_like (N, 3)
        Specific force, m/s², body frame.
    mag : array_like (N, 3) or None
        Magnetic field, body frame, any consistent unit; ``None``: 6D (the heading is the gyro's
        integral from heading zero, held at rest).
    rate_hz : float
        Sample rate (Hz), in (0, 1e6]; checked before anything is allocated.
    gyro_noise_density, gyro_bias_density, tilt_noise_density, heading_noise_density : float, optional
        Noise figures (:class:`~cfdesign.nav.AttitudeParams`; defaults
        :data:`~cfdesign.nav.quaternion_attitude.DEFAULT_NOISE`).
    declination_rad : float
        Magnetic declination, positive east (finite, within [-pi, pi]).
    gyro_bias_std0 : float
        Prior std of the gyro bias (rad/s), default 0.0175.
    initial : array_like (4,), optional
        Initial quaternion ``[w, x, y, z]`` (body -> ENU).
    correction_rate_hz : None
        No longer used: the filter corrects at every sample (a value other than None warns).
    return_bias : bool
        Also return the gyro bias estimate (N, 3), rad/s, body frame.
    tables : pair or dict, optional
        A user's own ``(tilt, heading)`` channel designs at ``rate_hz`` (``cf2`` order 2,
        discrete: :func:`cfdesign.nav.design_channel` or a FilterSpec); give either tables or
        the tilt and heading noise figures.
    **params
        Any other :class:`~cfdesign.nav.AttitudeParams` field.

    Returns
    -------
    ndarray (N, 4)
        Unit quaternions ``[w, x, y, z]`` (w >= 0), body -> ENU; with ``return_bias`` the tuple
        ``(quaternions, bias)``.

    Raises
    ------
    AttitudeInputError
        Wrong shapes, a bad rate or parameter, both tables and noise figures.
    TableMismatchError
        A table that is not the channel's model at the sample rate.

    Notes
    -----
    Missing data never yields a NaN quaternion: a non-finite or impossible rate holds the last
    good one; a non-finite, zero or impossible specific force skips the tilt correction; a
    non-finite or zero field skips the heading correction (counted: ``AttitudeFilter.missing``).

    The gyro bias is learnt fast at rest (seconds) and slowly in motion: a recording that starts
    at rest (a second or two still is enough) gets its bias before the motion; one that starts in
    motion carries it for tens of seconds (a bias of 0.02 rad/s: a few degrees of heading error
    over the first minute in 9D, against hundredths of a degree after a 5 s rest).  Start logging
    before the sensor moves where you can.
    """
    rate_hz = _rate(rate_hz)
    if correction_rate_hz is not None:
        warnings.warn("estimate_attitude: correction_rate_hz is no longer used (the filter corrects at every "
                      "sample)", DeprecationWarning, stacklevel=2)
    given = {name: value for name, value in (("tilt_noise_density", tilt_noise_density),
                                             ("heading_noise_density", heading_noise_density)) if value is not None}
    if tables is not None and given:
        raise AttitudeInputError(f"give either tables or the noise figures ({', '.join(given)}), not both")
    for name, value in (("gyro_noise_density", gyro_noise_density), ("gyro_bias_density", gyro_bias_density)):
        if value is not None:
            given[name] = value
    f = AttitudeFilter(rate_hz, magnetometer=mag is not None, initial=initial, tables=tables,
                       declination_rad=declination_rad, gyro_bias_std0=gyro_bias_std0, **given, **params)
    if not return_bias:
        return f.run(gyr, acc, mag)
    out = f.run(gyr, acc, mag, details=True)
    return out.quaternion, out.bias
