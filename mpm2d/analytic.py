"""Exact solutions of the verification problems, and fitting helpers.

All functions are vectorised numpy, SI units.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.special import j1, jn_zeros


def bar_mode1(t, v0: float, length: float, c: float):
    """Axial bar fixed at x = 0, free at x = L, started in mode 1 with v = v0 sin(pi x/2L).

    v(x, t) = v0 sin(pi x/(2L)) cos(omega t), omega = pi c/(2L). Returns the centre-of-mass
    velocity v0 (2/pi) cos(omega t) [m/s] and omega [rad/s].
    """
    omega = np.pi * c / (2.0 * length)
    return v0 * 2.0 / np.pi * np.cos(omega * np.asarray(t)), omega


def cylinder_mode1(radius: float, c: float):
    """Radial vibration of a solid cylinder (plane strain along z), u_r(R) = 0.

    u_r'' + u_r'/r - u_r/r^2 = u_r_tt/c^2 gives v_r = v0 J1(k r) cos(omega t), k = j_{1,1}/R,
    omega = k c. Returns (k [1/m], omega [rad/s]).
    """
    k = jn_zeros(1, 1)[0] / radius
    return k, k * c


def bessel_j1(x):
    return j1(x)


def fit_oscillation(t, y, omega0: float, rel_window: float = 0.2):
    """Least-squares fit y ~ a cos(omega t) + b sin(omega t); returns (amplitude, omega, phase).

    omega is searched within omega0 (1 +- rel_window); for each omega the amplitudes are linear.
    """
    t, y = np.asarray(t, float), np.asarray(y, float)

    def resid(w):
        A = np.stack([np.cos(w * t), np.sin(w * t)], axis=1)
        coef, *_ = np.linalg.lstsq(A, y, rcond=None)
        return np.sum((A @ coef - y) ** 2), coef

    res = minimize_scalar(lambda w: resid(w)[0], bounds=(omega0 * (1 - rel_window),
                                                         omega0 * (1 + rel_window)),
                          method="bounded", options={"xatol": omega0 * 1e-12})
    _, (a, b) = resid(res.x)
    return float(np.hypot(a, b)), float(res.x), float(np.arctan2(-b, a))


def couette_startup(y, t, gap: float, U: float, nu: float, nterms: int = 200):
    """Plane Couette startup: wall y = gap starts at U at t = 0, wall y = 0 fixed, fluid at rest.

    u(y, t) = U y/H + sum_k 2U(-1)^k/(k pi) sin(k pi y/H) exp(-nu k^2 pi^2 t/H^2) [m/s].
    """
    y = np.asarray(y, float)[..., None]
    k = np.arange(1, nterms + 1)
    terms = 2.0 * U * (-1.0) ** k / (k * np.pi) * np.sin(k * np.pi * y / gap) * np.exp(
        -nu * (k * np.pi / gap) ** 2 * t)
    return U * y[..., 0] / gap + terms.sum(axis=-1)


def _terzaghi_modes(t, height, cv, ramp_time, nterms):
    """M_m and the time factor of each mode for a load switched on at t = 0 (step), or by a
    half-cosine ramp q(s) = (1 - cos(pi s/t_r))/2 over t_r (Duhamel superposition, closed form)."""
    M = (2 * np.arange(nterms) + 1) * np.pi / 2.0
    t = np.asarray(t, float)[..., None]
    a = M * M * cv / height ** 2
    if ramp_time <= 0.0:
        return M, np.exp(-a * t)
    b = np.pi / ramp_time
    m = np.minimum(t, ramp_time)
    # int_0^m q'(s) exp(-a (t - s)) ds with q' = (b/2) sin(b s)
    factor = 0.5 * b * (np.exp(-a * (t - m)) * (a * np.sin(b * m) - b * np.cos(b * m))
                        + b * np.exp(-a * t)) / (a * a + b * b)
    return M, factor


def terzaghi_pressure(depth, t, height: float, p0: float, cv: float, ramp_time: float = 0.0,
                      nterms: int = 400):
    """Terzaghi consolidation: excess pore pressure [Pa] at ``depth`` below the drained top.

    Column of height H drained (p = 0) at the top, impermeable at the bottom. A load whose
    undrained pore pressure is p0 (= B q) is applied at t = 0 (``ramp_time`` = 0) or by a
    half-cosine ramp over ``ramp_time`` [s]:
    p = sum_m 2 p0/M sin(M z/H) g_m(t), M = (2m + 1) pi/2, g_m = exp(-M^2 cv t/H^2) for the
    step, its Duhamel integral over the ramp otherwise. ``depth`` and ``t`` broadcast.
    """
    z, t = np.broadcast_arrays(np.asarray(depth, float), np.asarray(t, float))
    M, g = _terzaghi_modes(t, height, cv, ramp_time, nterms)
    return (2.0 * p0 / M * np.sin(M * z[..., None] / height) * g).sum(axis=-1)


def terzaghi_mean_pressure(t, height: float, p0: float, cv: float, ramp_time: float = 0.0,
                           nterms: int = 400):
    """Depth-averaged excess pore pressure [Pa] (mean of sin(M z/H) is 1/M)."""
    M, g = _terzaghi_modes(t, height, cv, ramp_time, nterms)
    return (2.0 * p0 / M ** 2 * g).sum(axis=-1)


def ramp(t, ramp_time: float):
    """The half-cosine load ramp (1 - cos(pi t/t_r))/2, 1 after t_r [-]."""
    if ramp_time <= 0.0:
        return np.ones_like(np.asarray(t, float))
    x = np.clip(np.asarray(t, float) / ramp_time, 0.0, 1.0)
    return 0.5 * (1.0 - np.cos(np.pi * x))


def terzaghi_coefficients(E_oed: float, kappa: float, n: float, C: float):
    """Biot/Terzaghi constants of the two-phase model with a linear skeleton.

    With Darcy drag C [Pa s/m^2] the relative flux is n (v_f - v_s) = -(n^2/C) grad p, the
    skeleton's constrained modulus is E_oed = K + 4G/3 and the fluid's compressibility n/kappa:
    cv = (n^2/C)/(1/E_oed + n/kappa) [m^2/s]; the undrained (Skempton) ratio of pore pressure to
    applied load is B = 1/(1 + n E_oed/kappa). Returns (cv, B).
    """
    return (n * n / C) / (1.0 / E_oed + n / kappa), 1.0 / (1.0 + n * E_oed / kappa)


def hindered_settling_velocity(phi: float, rho_s: float, rho_f: float, g: float, C: float):
    """Settling speed of grains in a closed column (zero net volume flux) [m/s].

    Steady Table 8 balances without skeleton stress: C (v_s - v_f) = phi n (rho_s - rho_f) g and
    phi v_s + n v_f = 0 give |v_s| = n^2 phi (rho_s - rho_f) g / C.
    """
    n = 1.0 - phi
    return n * n * phi * (rho_s - rho_f) * g / C


def observed_orders(h, err):
    """Observed orders log(e_i/e_{i+1})/log(h_i/h_{i+1}) along the first axis of ``err``."""
    h, err = np.asarray(h, float), np.asarray(err, float)
    h = h.reshape(h.shape + (1,) * (err.ndim - 1))
    return np.log(err[:-1] / err[1:]) / np.log(h[:-1] / h[1:])
