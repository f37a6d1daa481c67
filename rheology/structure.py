"""Micro-structure f: Eqs. (3)-(9), (16) and the Table 8 evolution law, for a Material.

All functions are vectorised over numpy arrays (broadcasting) and validate their inputs.
"""

from __future__ import annotations

import numpy as np

from . import laws
from runkit.params import check_nonnegative, check_positive, check_range
from .materials import Material, get_material


def _phi(phi, m: Material) -> np.ndarray:
    return check_range("phi", phi, 0.0, 1.0, hi_closed=False, note=f"material {m.name}")


def _taubar(taubar, m: Material) -> np.ndarray:
    """Granular shear stress in [0, 1e100 tau*] (beyond, H = (taubar/tau*)^(3/2) overflows)."""
    return check_range("taubar", taubar, 0.0, 1e100 * m.tau_star,
                       note=f"1e100 tau* of {m.name}: beyond, H = (taubar/tau*)^(3/2) overflows")


def _f(f) -> np.ndarray:
    return check_range("f", f, 0.0, 1.0)


def phi_m(f, m: Material | str) -> np.ndarray:
    """Eq. (3): jamming fraction phi_m(f) = phi_j + (phi_c - phi_j) f [-], f in [0, 1]."""
    m = get_material(m)
    return laws.phi_m(_f(f), m.phi_c, m.phi_j)


def dilatancy_a(f, m: Material | str) -> np.ndarray:
    """Eq. (4): dilation parameter a(f) = a0 + (a_inf - a0) f [-], f in [0, 1]."""
    m = get_material(m)
    return laws.dilatancy_a(_f(f), m.a0, m.a_inf)


def f_max(phi, m: Material | str) -> np.ndarray:
    """Eq. (8): upper bound f_m(phi) of the steady structure [-]."""
    m = get_material(m)
    return laws.f_max(_phi(phi, m), m.phi_c, m.phi_j, m.Delta)


def f_jam(phi, m: Material | str) -> np.ndarray:
    """Structure at which phi_m(f) = phi, i.e. (phi_j - phi)/(phi_j - phi_c) [-] (> 1: never jams)."""
    m = get_material(m)
    return (m.phi_j - _phi(phi, m)) / (m.phi_j - m.phi_c)


def eta_B(phi, m: Material | str) -> np.ndarray:
    """Eq. (9): buckling resistance eta_B(phi) [Pa s]; ``inf`` where every varphi_i is zero."""
    m = get_material(m)
    inv = laws.inv_eta_B(_phi(phi, m), m.phi_j, m.varphi1, m.alpha1, m.varphi2, m.alpha2)
    with np.errstate(divide="ignore"):
        return np.where(inv > 0, 1.0 / np.where(inv > 0, inv, 1.0), np.inf)


def hardening(taubar, m: Material | str) -> np.ndarray:
    """Eq. (6): H = (taubar/tau*)^(3/2) [-], taubar the granular shear stress [Pa] >= 0."""
    m = get_material(m)
    return laws.hardening(_taubar(taubar, m), m.tau_star)


def softening(taubar, gdot_p, phi, m: Material | str) -> np.ndarray:
    """Eq. (7): S = 1 + taubar/(eta_B gdot_p) + xi_eps/gdot_p [-], gdot_p > 0 [1/s]."""
    m = get_material(m)
    g = check_range("gdot_p", gdot_p, 0.0, None, lo_closed=False)
    inv = laws.inv_eta_B(_phi(phi, m), m.phi_j, m.varphi1, m.alpha1, m.varphi2, m.alpha2)
    return 1.0 + (check_nonnegative("taubar", taubar) * inv + m.xi_eps) / g


def _law_args(f, taubar, gdot_p, phi, m: Material) -> tuple:
    """The checked arguments of :func:`rheology.laws.structure_rate` (and ``structure_step``)."""
    m.require("K0")
    phi = _phi(phi, m)
    inv = laws.inv_eta_B(phi, m.phi_j, m.varphi1, m.alpha1, m.varphi2, m.alpha2)
    return (_f(f), _taubar(taubar, m), check_nonnegative("gdot_p", gdot_p),
            laws.f_max(phi, m.phi_c, m.phi_j, m.Delta), m.tau_star, inv, m.K0, m.xi_eps)


def structure_rate(f, taubar, gdot_p, phi, m: Material | str) -> np.ndarray:
    """Table 8 structure law df/dt [1/s] with gdot_p the plastic shear rate [1/s]."""
    return laws.structure_rate(*_law_args(f, taubar, gdot_p, phi, get_material(m)))


def structure_step(f, taubar, gdot_p, phi, dt: float, m: Material | str) -> np.ndarray:
    """One backward-Euler step of the structure law at fixed (taubar, gdot_p) [-]; dt [s] > 0."""
    args = _law_args(f, taubar, gdot_p, phi, get_material(m))
    check_range("dt", dt, 0.0, None, lo_closed=False)
    return laws.structure_step(*args, dt)


# ------------------------------------------------------------- steady f(tau): Eq. (16) and rivals
def steady_f_of_stress(tau, tau_star: float) -> np.ndarray:
    """Eq. (16)-(17): steady f = H/(H + 1), H = (tau/tau*)^(3/2) (negligible buckling) [-]."""
    tau_star = check_positive("tau_star", tau_star)
    tau = check_nonnegative("tau", tau)
    with np.errstate(divide="ignore", over="ignore"):    # written as 1/(1 + H^-1): no overflow
        inv_h = (tau_star / np.where(tau > 0, tau, 1.0)) ** 1.5
        return np.where(tau > 0, 1.0 / (1.0 + inv_h), 0.0)


def wyart_cates_f(tau, tau_star: float) -> np.ndarray:
    """Wyart & Cates (2014) fraction of frictional contacts, f = 1 - exp(-tau/tau*) [-]."""
    tau_star = check_positive("tau_star", tau_star)
    return 1.0 - np.exp(-check_nonnegative("tau", tau) / tau_star)


def singh_f(tau, tau_star: float) -> np.ndarray:
    """Singh et al. (2018) fraction of frictional contacts, f = exp(-tau*/tau) [-] (0 at tau = 0)."""
    tau_star = check_positive("tau_star", tau_star)
    tau = check_nonnegative("tau", tau)
    with np.errstate(divide="ignore"):
        return np.where(tau > 0, np.exp(-tau_star / np.where(tau > 0, tau, 1.0)), 0.0)
