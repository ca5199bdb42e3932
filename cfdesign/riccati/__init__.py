"""Algebraic Riccati equations: checked, refined, named results.

Continuous (CARE), discrete (DARE) and periodic discrete (filter form) Riccati equations,
plus the two steady-state Kalman estimator helpers built on them.  Every solver validates
its data with messages that name the matrix, names the offending mode when a PBH (Hautus)
test rules a stabilising solution out, refines a first estimate by Newton's method on a
double-double residual, certifies the closed loop and returns a frozen, named result, or
raises an error of the :class:`~cfdesign.errors.RiccatiError` family.  A closed loop whose
margin cannot be resolved from the boundary is flagged ``marginal=True`` with a warning,
never passed off as stabilising.

Conventions follow :func:`scipy.linalg.solve_continuous_are` and
:func:`scipy.linalg.solve_discrete_are` (control form, ``'`` is the conjugate transpose).
The estimator helpers name their gain forms (``K_filter`` for the measurement update
``x+ = x- + K (z - H x-)``, ``K_predictor`` for ``x[k+1] = F x + B u + K (z - H x)``): the
two are never mixed silently.

Modules
-------
api
    :func:`care`, :func:`dare`, :func:`kalman_continuous`, :func:`kalman_discrete` and the
    solve pipeline.
periodic
    :func:`periodic_dare`.
results
    The frozen result classes.
validation
    Matrix checks and PBH mode tests.
refinement, lyapunov, extended
    Newton refinement, the linearised Riccati operators, double-double arithmetic.
stability
    Certification of the closed loop.
fallbacks
    First estimates: scipy, the matrix sign function, structure-preserving doubling, scipy unbalanced.
problem
    The validated data of one equation and the algebra the stages share.
"""

from .api import care, dare, kalman_continuous, kalman_discrete
from .periodic import periodic_dare
from .results import ContinuousKalmanGains, DiscreteKalmanGains, PeriodicSolution, RiccatiSolution

__all__ = [
    "RiccatiSolution",
    "ContinuousKalmanGains",
    "DiscreteKalmanGains",
    "PeriodicSolution",
    "care",
    "dare",
    "kalman_continuous",
    "kalman_discrete",
    "periodic_dare",
]
