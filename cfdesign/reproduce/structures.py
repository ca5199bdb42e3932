"""Band assignments as observers: which sensor drives the filter and which are measured.

A complementary filter's bands are fixed by how each sensor enters the observer
(``docs/derivations.md``, sections "One observer" and "Three-band filters"), so an
assignment "low-pass X, band-pass Y, high-pass Z" (Carreira et al., Tables I and II) is a
structure:

* **high-pass** - the *input*: the sensor's rate drives ``x[k+1] = F x + B u``, with a
  rate-correction state that absorbs its rate bias.  Its band is ``(z - 1)^2/den``: no DC,
  no ramp, so a constant rate bias (odometry's drift) cannot reach the estimate.
* **low-pass** - a heading *measurement* with a path to the rate-correction state: it
  carries the estimate's DC (its band's DC gain is 1).
* **band-pass** - a second heading measurement whose innovation does not reach the
  rate-correction state: the gain entry ``k22`` of the DCKF³ is held at zero, and its band
  ``k12 (z - 1)/den`` has no DC.

Two sensors (Table I): ``cf2(order=2, discrete=True)`` with the high-pass sensor as its
rate input and the low-pass sensor as its angle; its Kalman gain is optimal.  Three sensors
(Table II): the DCKF³ of Carreira et al. eqs. (25)-(27) with ``k22 = 0``: the gains are the best
this band assignment allows (the designer's rule for sparse gain patterns: minimum
steady-state error variance ``P[0, 0]``), the CF³ of the paper.  Sensors are renamed after
the physical sensor in each port; a heading sensor in the input port is fed its
differenced heading, a gyro in a measurement port its dead-reckoned heading
(:mod:`cfdesign.sim.signals`).
"""

from __future__ import annotations

__all__ = ["banded_observer", "design_observer"]


def banded_observer(low: str, high: str, band: str | None = None):
    """The discrete observer that puts ``low``, ``band`` and ``high`` in those bands.

    Two sensors: ``cf2(order=2, discrete=True)`` with ports ``rate <- high``, ``angle <- low``;
    bands ``T_high = (z - 1)^2/den``, ``T_low = (k1 (z - 1) + T k2)/den``.
    Three sensors: the DCKF³ of Carreira et al. eqs. (25)-(27) with ``k22 = 0``, ports
    ``gyro <- high``, ``compass <- low``, ``odometry <- band``; with eq. (32)'s denominator
    ``den = z^2 + (k11 + k12 - 2) z + 1 - k11 - k12 + T k21``:

        T_high = (z - 1)^2/den,  T_low = (k11 (z - 1) + T k21)/den,  T_band = k12 (z - 1)/den.

    Parameters
    ----------
    low, high : str
        Sensor names (identifiers) in the low-pass band (a heading measurement) and the
        high-pass band (the rate input, with a bias state).
    band : str, optional
        Sensor in the band-pass band (a heading measurement with no path to the bias state).

    Returns
    -------
    Observer
        Discrete (``z``, sample time ``T`` symbolic), predictor gain form, gains symbolic.
    """
    from ..symbolic import cf2, dckf3

    if band is None:
        return cf2(order=2, discrete=True).renamed({"rate": high, "angle": low}, f"cf2: LP {low}, HP {high}")
    return dckf3().subs(k22=0).renamed({"gyro": high, "compass": low, "odometry": band},
                                       f"cf3: LP {low}, BP {band}, HP {high}")


def design_observer(spec, observer):
    """:func:`~cfdesign.designer.design` for an observer built on the engine rather than named in ``spec``.

    The same path as the designer - sensor checks, multirate schedule, noise covariances,
    Van Loan, DARE (Carreira et al. eq. (28), predictor form of eq. (25)) or, for a sparse gain
    pattern, the gains minimising the steady-state ``P[0, 0]``, exact checks - with
    ``observer`` in place of ``build_structure(spec)``.

    Parameters
    ----------
    spec : FilterSpec
        Sensors named as the observer's; ``structure`` is only a label here.
    observer : Observer
        Discrete, with symbolic gains.

    Returns
    -------
    GainTable
        The designed gain table.

    """
    from ..designer import design

    return design(spec, observer)
