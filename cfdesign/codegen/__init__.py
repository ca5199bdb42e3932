"""C99 code generation: a designed gain table as a portable, allocation-free C filter.

:func:`write_c` writes three files for a discrete table (``predictor`` or ``filter`` gain
form; a continuous table is refused):

* ``<prefix>_gains.h``: dimensions, period, sample time, wrap flag, sensor index macros
  (``<PREFIX>_U_<INPUT>``, ``<PREFIX>_Y_<MEASUREMENT>``), ``<PREFIX>_MISSING`` (a finite
  reading beyond the limit: missing without NaN, so also under ``-ffast-math``), the phase of
  each sensor a multirate schedule reads once a period (``<PREFIX>_PHASE_<MEASUREMENT>``: set
  ``s->phase`` to it before the step of each of its readings, to lock the schedule to that
  sensor; one read at several phases is listed in a comment, without a macro) and the ``F, B, H, K`` arrays as
  ``static const`` with every value in full precision, under a do-not-edit comment with the
  table's provenance;

  (every file's comment also states the base rate - one step call per base step -, the estimate
  the step returns, when each sensor is read, and the table's
  :func:`~cfdesign.runtime.filter.filter_sha256`, the one a Python state of it records)
* ``<prefix>_filter.h``: ``typedef double|float <prefix>_real``, the plain-data state
  ``<prefix>_state {x, u_last, phase}``, ``<prefix>_init`` and ``<prefix>_step``;
* ``<prefix>_filter.c``: the step, C99 with ``<math.h>`` only (``ceil`` or ``ceilf``, for the angle wrap), no
  allocation, no globals beyond the constant tables.

The step has the semantics of :meth:`cfdesign.runtime.Runtime.step` (NaN is a missing
reading: inputs hold their last value, measurements are skipped; angle tables wrap angle
innovations, the state's angle and the estimate to (-pi, pi]) and its operation order: the
matrix products are written out as sums accumulated from their first term, leaving out
terms whose coefficient is zero (for K: zero at every phase), which for finite numbers
changes nothing.  One deliberate difference: an angle already in (-pi, pi] is kept as it
is, where the runtime's wrap formula re-rounds it by up to a few ulps; angles outside use
the runtime's formula.

Agreement with the Python runtime, as ``tests/test_codegen.py`` checks it (100,000 samples of
a slow sinusoid plus noise with 2 % missing readings; the DCKF3 example of Carreira et al. ("dckf3") with the
heading crossing +-pi, compared modulo 2 pi; the multirate position table, period 50):

* ``precision='double'``: ``max |C - Python| <= 1e-12`` required; measured 0, bit-identical
  (robot heading and position), with GCC 12 and Clang 14 -O2 on x86-64.  This assumes
  IEEE double arithmetic without extended precision or contraction into fused
  multiply-adds (the default with ``-std=c99``); with ``-ffast-math`` or on x87 the agreement is
  to rounding (measured at most 1.6e-14 relative), and missing readings must be ``<PREFIX>_MISSING``,
  not NaN or inf (Clang 14 ``-O3 -ffast-math`` let a NaN reading into the state).
* ``precision='float'``: single-precision rounding; the documented bound is
  ``max |C - Python| <= 2e-6 x max |estimate|`` for the robot heading (measured 1.9e-7 x)
  and ``<= 1e-4 x max |estimate|`` for the position (measured 1.9e-5 x: the float position
  state, ulp 7.6e-6 m at 64 m, is integrated at 50 Hz between 1 Hz GPS fixes).  Other tables:
  the float error grows with the filter's memory, within ``8 x 2**-24 x max |estimate| x ||h||_1``
  (``||h||_1``: the sum of ``|h_k|``,
  ``h`` the closed loop's response of the estimate to a unit error in the state; roundings that
  repeat step after step, as when a slowly varying increment is added to a large position, add up
  over it).  Where the roundings average out the error is nearer ``8 x 2**-24 x max |estimate| x
  ||h||_2`` (``||h||_2`` 4.7 for the robot heading, 300 for a 50 Hz gyro with 10 Hz and 5 Hz
  compasses, measured ``3.3e-6 x max |estimate|`` there); a 200 Hz CKF3 whose position drifts to
  1.5e5 m exceeds that figure 2.9 times (``||h||_2`` 22, ``||h||_1`` 1000).  Every figure measured
  here: ``python benchmarks/bench_runtime.py --c-agreement``.

Every generated file compiles clean under :data:`~cfdesign.codegen.c99.STRICT_CFLAGS` (C99) and
:data:`~cfdesign.codegen.c99.STRICT_CXXFLAGS` (C++11), the warning sets the C export promises; every name
with file scope starts with the prefix.

The step costs about 8 ns for the DCKF3 in double on an x86-64 (8.2 ns beside 5.0 ns for a one-pole IIR
in the same loop: ``python benchmarks/bench_runtime.py``, section iii).
"""

from .c99 import (
    C99_KEYWORDS,
    STRICT_CFLAGS,
    STRICT_CXXFLAGS,
    check_c_identifier,
    check_c_names,
    check_c_prefix,
    render_c,
    write_c,
)

__all__ = ["write_c", "render_c", "check_c_identifier", "check_c_prefix", "check_c_names", "C99_KEYWORDS",
           "STRICT_CFLAGS", "STRICT_CXXFLAGS"]
