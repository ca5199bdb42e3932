"""cfdesign's attitude filter on BROAD beside Madgwick, Mahony (package ``ahrs``) and VQF (``vqf``).

Data: D. Laidig, M. Caruso, A. Cereatti, T. Seel, "BROAD - A Benchmark for Robust Inertial
Orientation Estimation", Data 6(7), 2021, doi:10.3390/data6070072 (CC BY 4.0).  The ten
development trials live in ``shared/data/broad`` beside the checkout.

Metric (the dataset's own, as in BROAD's ``example_code/broad_utils.py``): ``e = q_est ⊗
conj(q_ref)`` (error in the Earth frame); total ``2 acos|e_w|``, heading ``2 atan|e_z/e_w|``,
inclination ``2 acos sqrt(e_w² + e_z²)``; RMSE in degrees over samples with ``movement == 1``
and a finite reference.  No heading offset is removed: BROAD's reference is already
expressed in ENU and its own evaluation compares directly; every filter is treated alike.
``ahrs``' Madgwick estimates in a north-west-up frame (x toward magnetic north) and is turned
into ENU by ``q_z(90°) ⊗ q``, as BROAD's ``process_data.py`` does; ``ahrs``' Mahony output is
compared as it is (with the ``q_z(90°)`` turn its heading error is 85-90° on every trial, without
it the errors are in line with BROAD's published figures).  All filters start from the first
accelerometer/magnetometer sample.

Parameters: Madgwick ``beta = 0.12``, Mahony ``Kp = 0.74, Ki = 0.0012`` (BROAD's best common
values over all 39 trials), VQF defaults, cfdesign ``estimate_attitude`` defaults (noise
densities, see its docstring).

Run::

    python benchmarks/bench_broad.py [--data PATH]

Optional dependencies (bench only, never needed by cfdesign): ``pip install ahrs==0.4.0 vqf``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from cfdesign import rotations as rot
from cfdesign.nav import estimate_attitude
from cfdesign.nav.broad import broad_rmse, load_trial

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "broad"
ENU_FROM_NWU = np.array([np.sqrt(0.5), 0.0, 0.0, np.sqrt(0.5)])


load = load_trial
rmse = broad_rmse


def initial_quaternion(d):
    """First-sample attitude (body -> ENU) from the MPS, shared by every filter."""
    from cfdesign.nav import mps_quaternion
    return mps_quaternion(d["acc"][0], d["mag"][0])


def run_cfdesign(d):
    return estimate_attitude(d["gyr"], d["acc"], d["mag"], d["rate"])


def run_madgwick(d):
    from ahrs.filters import Madgwick
    q0 = rot.multiply(rot.conjugate(ENU_FROM_NWU), initial_quaternion(d))
    q = Madgwick(gyr=d["gyr"], acc=d["acc"], mag=d["mag"], frequency=d["rate"], gain=0.12, q0=q0).Q
    return rot.multiply(ENU_FROM_NWU, q)


def run_mahony(d):
    from ahrs.filters import Mahony
    q0 = initial_quaternion(d)
    return Mahony(gyr=d["gyr"], acc=d["acc"], mag=d["mag"], frequency=d["rate"], k_P=0.74, k_I=0.0012, q0=q0).Q


def run_vqf(d):
    from vqf import VQF
    f = VQF(1.0 / d["rate"])
    return f.updateBatch(d["gyr"], d["acc"], d["mag"])["quat9D"]


FILTERS = {"cfdesign": (run_cfdesign, None), "madgwick": (run_madgwick, "ahrs"),
           "mahony": (run_mahony, "ahrs"), "vqf": (run_vqf, "vqf")}


def available():
    names = []
    for name, (_, module) in FILTERS.items():
        if module is not None:
            try:
                __import__(module)
            except ImportError:
                print(f"skipping {name}: optional package '{module}' is not installed "
                      f"(pip install {'ahrs==0.4.0' if module == 'ahrs' else module})")
                continue
        names.append(name)
    return names


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=DATA, help="folder of BROAD .mat trials")
    args = parser.parse_args(argv)
    files = sorted(args.data.glob("*.mat"))
    if not files:
        print(f"no BROAD trials (*.mat) in {args.data}")
        return 1
    names = available()
    table = {n: [] for n in names}
    times = {n: [] for n in names}
    header = "trial".ljust(34) + "".join(f"{n:>24}" for n in names)
    print("RMSE deg (total / heading / inclination), then the time per trial in ms")
    print(header)
    for path in files:
        d = load(path)
        # the gain design (sympy + DARE, ~1 s) is cached per rate: do it before timing the filter
        estimate_attitude(d["gyr"][:2], d["acc"][:2], d["mag"][:2], d["rate"])
        row = path.stem[:33].ljust(34)
        for n in names:
            t = time.perf_counter()
            q = FILTERS[n][0](d)
            times[n].append(time.perf_counter() - t)
            table[n].append(rmse(q, d["ref"], d["movement"]))
            tot, hd, inc = table[n][-1]
            row += f"{tot:6.2f}/{hd:5.2f}/{inc:5.2f}{1000 * times[n][-1]:6.0f}"
        print(row)
    row = "mean".ljust(34)
    for n in names:
        tot, hd, inc = np.mean(table[n], axis=0)
        row += f"{tot:6.2f}/{hd:5.2f}/{inc:5.2f}{1000 * np.mean(times[n]):6.0f}"
    print(row)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
