"""Exact Newtonian solutions used to verify the 1-D solver (SI units)."""

from __future__ import annotations

import numpy as np

from runkit.params import check_nonnegative, check_positive


def plane_couette_startup(y, t: float, gap: float, speed: float, nu: float) -> np.ndarray:
    """Impulsively started plane Couette flow of a Newtonian fluid [m/s].

    The wall at y = 0 moves at ``speed`` from t = 0+, the wall at y = gap is at rest, the fluid is
    at rest at t = 0: ``v = U (1 - y/H) - (2U/pi) sum_n sin(n pi y/H) exp(-n^2 pi^2 nu t/H^2)/n``.
    The series is summed until its terms fall below 1e-17 U.

    Parameters
    ----------
    y : array_like
        Positions in [0, gap] [m].
    t : float
        Time [s] > 0.
    gap, speed, nu : float
        Gap H [m], wall speed U [m/s], kinematic viscosity [m^2/s].
    """
    check_positive("t", t, note="s")
    check_positive("gap", gap, note="m")
    check_positive("nu", nu, note="m^2/s")
    y = np.asarray(y, dtype=float)
    x = y / gap
    decay = np.pi ** 2 * nu * t / gap ** 2
    n_max = int(np.ceil(np.sqrt(40.0 / decay))) + 1
    n = np.arange(1, n_max + 1)[:, None]
    series = np.sum(np.sin(n * np.pi * x[None, ...].reshape(1, -1)) * np.exp(-n ** 2 * decay) / n,
                    axis=0).reshape(x.shape)
    return speed * (1.0 - x) - 2.0 * speed / np.pi * series


def annular_steady(r, r_inner: float, r_outer: float, speed: float) -> np.ndarray:
    """Steady Newtonian annular Couette profile v = A r + B/r [m/s], inner surface at ``speed``,
    outer at rest: A = -U R_i/(R_o^2 - R_i^2), B = U R_i R_o^2/(R_o^2 - R_i^2) (any viscosity).
    """
    check_positive("r_inner", r_inner, note="m")
    check_positive("r_outer - r_inner", r_outer - r_inner, note="m")
    r = check_nonnegative("r", r)
    d = r_outer ** 2 - r_inner ** 2
    return -speed * r_inner / d * r + speed * r_inner * r_outer ** 2 / d / r
