"""Vectorised pieces of the Table 8 granular flow rule, for a Material.

These are the same laws the local update (:mod:`rheology.local_update`) uses, exposed on numpy
arrays so that callers and tests can check a solution: stress invariants, inertial numbers,
friction, critical-state packing, dilation angle, the plastic flow-rate tensor (Eq. 10), the yield
functions f_1, f_2, f_3 and the plastic dissipation. Stresses are (..., 3, 3) tensors [Pa],
tension positive.
"""

from __future__ import annotations

import numpy as np

from . import laws
from runkit.params import check_nonnegative, check_positive, check_range
from .materials import Material, get_material


def _stress(stress) -> np.ndarray:
    """(..., 3, 3) finite stresses, else ValueError naming ``stress``."""
    sig = check_range("stress", stress)
    if sig.ndim < 2 or sig.shape[-2:] != (3, 3):
        raise ValueError(f"stress must have shape (..., 3, 3), got {sig.shape}")
    return sig


def invariants(stress) -> tuple[np.ndarray, np.ndarray]:
    """Eq. (11): (taubar, p) = (sqrt(s:s/2), -tr(sigma)/3) of (..., 3, 3) stresses [Pa].

    Raises ValueError for a non-finite stress or a shape other than (..., 3, 3).
    """
    sig = _stress(stress)
    p = -np.trace(sig, axis1=-2, axis2=-1) / 3.0
    s = sig + p[..., None, None] * np.eye(3)
    return np.sqrt(0.5 * np.einsum("...ij,...ij->...", s, s)), p


def inertial_numbers(gdot_p, p, m: Material | str):
    """Table 8: (I, I_v, I_m) for plastic rate gdot_p [1/s] >= 0 and pressure p [Pa] > 0."""
    m = get_material(m)
    g, p = check_nonnegative("gdot_p", gdot_p), check_positive("p", p)
    with np.errstate(all="ignore"):
        out = laws.inertial_numbers(g, p, m.eta0, m.d, m.rho_s or 0.0)
    _finite(out, "gdot_p and p", "the inertial numbers")
    return out


def _finite(arrays, names: str, what: str) -> None:
    """ValueError if an overflow left a non-finite value in ``arrays``, naming the inputs."""
    if not all(np.all(np.isfinite(a)) for a in arrays):
        raise ValueError(f"{names}: {what} overflow double precision (values too extreme; "
                         f"valid: results below 1e308)")


def friction(I_v, I_m, phi, f, m: Material | str) -> np.ndarray:
    """Table 8: mu_p(I_v, I_m) = mu_1 + (mu_2 - mu_1)/(1 + b/I_m) + 5/2 phi I_v/(a I_m) [-]."""
    m = get_material(m)
    a = laws.dilatancy_a(check_range("f", f, 0.0, 1.0), m.a0, m.a_inf)
    return laws.friction(check_nonnegative("I_v", I_v), check_nonnegative("I_m", I_m),
                         check_range("phi", phi, 0.0, 1.0, hi_closed=False), a, m.mu_c, m.mu2, m.b)


def phi_equilibrium(I_m, f, m: Material | str) -> np.ndarray:
    """Table 8: phi_eq = phi_m(f)/(1 + a(f) I_m) [-]."""
    m = get_material(m)
    f = check_range("f", f, 0.0, 1.0)
    return laws.phi_equilibrium(laws.phi_m(f, m.phi_c, m.phi_j), laws.dilatancy_a(f, m.a0, m.a_inf),
                                check_nonnegative("I_m", I_m))


def dilation_angle(phi, I_m, f, m: Material | str) -> np.ndarray:
    """Table 8: beta = K3 (phi - phi_eq) [-]."""
    m = get_material(m)
    phi = check_range("phi", phi, 0.0, 1.0, hi_closed=False)
    return laws.dilation_angle(phi, phi_equilibrium(I_m, f, m), m.K3)


def plastic_flow_rate(stress, gdot_p, beta, xi1=0.0, xi2=0.0) -> np.ndarray:
    """Eq. (10): D^p = gdot_p/(2 taubar) (sigma + p 1) + (beta gdot_p + xi1 + xi2)/3 1 [1/s].

    stress (..., 3, 3) [Pa]; gdot_p >= 0 [1/s]; beta [-]; xi1 >= 0 (separation) and xi2 <= 0
    (compaction) [1/s]; all finite, else ValueError naming the parameter.
    """
    sig = _stress(stress)
    gdot_p = check_nonnegative("gdot_p", gdot_p)
    beta = check_range("beta", beta)
    xi1 = check_nonnegative("xi1", xi1)
    xi2 = check_range("xi2", xi2, None, 0.0)
    taubar, p = invariants(sig)
    s = sig + p[..., None, None] * np.eye(3)
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.where(taubar > 0, np.asarray(gdot_p) / (2.0 * np.where(taubar > 0, taubar, 1.0)), 0.0)
    vol = (np.asarray(beta) * gdot_p + xi1 + xi2) / 3.0
    return k[..., None, None] * s + np.asarray(vol)[..., None, None] * np.eye(3)


def plastic_dissipation(stress, gdot_p, beta, xi1=0.0, xi2=0.0) -> np.ndarray:
    """Plastic power sigma : D^p [W/m^3] = gdot_p taubar - p (beta gdot_p + xi1 + xi2)."""
    Dp = plastic_flow_rate(stress, gdot_p, beta, xi1, xi2)
    return np.einsum("...ij,...ij->...", _stress(stress), Dp)


def yield_functions(stress, gdot_p, phi, f, m: Material | str, xi2=0.0):
    """Table 8 yield functions (f_1, f_2, f_3) [Pa] at a state (K4 = 0: zeta = gdot_p).

    f_1 = taubar - max((mu_p + beta) p, 0), f_2 = -p, f_3 = g(phi) p - (a phi)^2 (zeta^2 d^2 rho_s
    + 2 eta0 zeta). A converged local update has f_1 = 0 while gdot_p > 0, f_1 <= 0 otherwise,
    f_3 = 0 while xi_2 < 0 and f_3 <= 0 otherwise.
    """
    m = get_material(m)
    taubar, p = invariants(stress)
    phi = check_range("phi", phi, 0.0, 1.0, hi_closed=False)
    f = check_range("f", f, 0.0, 1.0)
    g = check_nonnegative("gdot_p", gdot_p)
    xi2 = check_range("xi2", xi2, None, 0.0)
    with np.errstate(all="ignore"):
        phim = laws.phi_m(f, m.phi_c, m.phi_j)
        a = laws.dilatancy_a(f, m.a0, m.a_inf)
        rho_s = m.rho_s or 0.0
        flowing = (p > 0) & (g > 0)
        ps, gs = np.where(flowing, p, 1.0), np.where(flowing, g, 0.0)   # rest or no contact: I = 0
        I, I_v, I_m = laws.inertial_numbers(gs, ps, m.eta0, m.d, rho_s)
        beta = laws.dilation_angle(phi, laws.phi_equilibrium(phim, a, I_m), m.K3)
        mu = laws.friction(I_v, I_m, phi, a, m.mu_c, m.mu2, m.b)
        f1 = taubar - np.maximum((mu + beta) * np.maximum(p, 0.0), 0.0)
        zeta = g - m.K4 * np.asarray(xi2)
        gphi = np.where(phi < phim, (phim - phi) ** 2, 0.0)
        f3 = gphi * p - (a * phi) ** 2 * (zeta ** 2 * m.d ** 2 * rho_s + 2.0 * m.eta0 * zeta)
    out = np.broadcast_arrays(f1, -p, f3)
    _finite(out, "stress, gdot_p and xi2", "the yield functions")
    return tuple(np.array(x) for x in out)
