"""The model's point-wise laws, written once as plain arithmetic.

Every function here takes numbers (scalars or broadcastable numpy arrays) and explicit scalar
parameters, uses only arithmetic, ``np.sqrt``, ``np.maximum``, ``np.minimum`` and the log and
exp of :mod:`rheology.vecmath` (numpy's from Python, SIMD-friendly under numba), and has no
branches, so the same source serves the public numpy API and, through ``register_jitable``, the
numba local-update kernel (:mod:`rheology.local_update`). The public functions in
:mod:`rheology.structure`, :mod:`rheology.steady` and :mod:`rheology.flow_rule` take a
:class:`~rheology.materials.Material`, validate their input and call these.

Symbols (paper's Table 8): phi volume fraction, f structure, phi_m, a dilation parameters,
taubar equivalent granular shear stress [Pa], p granular pressure [Pa], gdot_p plastic shear rate
[1/s], I, I_v, I_m inertial, viscous and mixed inertial numbers.
"""

from __future__ import annotations

import numpy as np
from numba.extending import register_jitable

from rheology import vecmath

#: Smallest positive number used to keep 0/0 limits finite (e.g. I_v/I_m at rest).
TINY = 1e-300


# ------------------------------------------------------------------ structure (Eqs. 3-9, Table 8)
@register_jitable
def phi_m(f, phi_c, phi_j):
    """Eq. (3): jamming fraction phi_m = phi_j + (phi_c - phi_j) f [-]."""
    return phi_j + (phi_c - phi_j) * f


@register_jitable
def dilatancy_a(f, a0, a_inf):
    """Eq. (4): dilation parameter a = a0 + (a_inf - a0) f [-]."""
    return a0 + (a_inf - a0) * f


@register_jitable
def f_max(phi, phi_c, phi_j, Delta):
    """Eq. (8): upper bound f_m of the steady structure [-].

    1 for phi <= phi_c, (phi_j - phi)/(phi_j - phi_c) up to phi*, Delta beyond phi*
    (phi* = phi_j + (phi_c - phi_j) Delta), i.e. clip((phi_j - phi)/(phi_j - phi_c), Delta, 1).
    """
    return np.minimum(1.0, np.maximum(Delta, (phi_j - phi) / (phi_j - phi_c)))


@register_jitable(inline="always")     # inlined: a loop over points that calls it is SIMD
def inv_eta_B(phi, phi_j, varphi1, alpha1, varphi2, alpha2):
    """Eq. (9): 1/eta_B = sum_i varphi_i (phi_j - phi)^alpha_i [1/(Pa s)]; 0 means eta_B = inf.

    The powers as exp(alpha_i ln x), one logarithm for both (cheaper than two pow calls; < 1e-14
    relative), exact at x = 0 (phi >= phi_j) without a branch: 0^alpha = 0 for alpha > 0, 1 for
    alpha = 0. Under numba log and exp are :mod:`rheology.vecmath`'s (<= 1 ulp), so a loop over
    points that calls this compiles to SIMD.
    """
    x = np.maximum(phi_j - phi, 0.0)
    lx = vecmath.log(np.maximum(x, TINY))
    pos, zero = x > 0.0, x <= 0.0
    return (varphi1 * (pos * vecmath.exp(alpha1 * lx) + zero * (alpha1 == 0.0))
            + varphi2 * (pos * vecmath.exp(alpha2 * lx) + zero * (alpha2 == 0.0)))


@register_jitable
def hardening(taubar, tau_star):
    """Eq. (6): H = (taubar/tau*)^(3/2) [-] (as t sqrt(t): a square root instead of a pow)."""
    t = np.maximum(taubar, 0.0) / tau_star
    return t * np.sqrt(t)


@register_jitable
def structure_rate(f, taubar, gdot_p, fm, tau_star, inv_etaB, K0, xi_eps):
    """Table 8: df/dt = K0 gdot_p H (f_m - f) - K0 (gdot_p + taubar/eta_B + xi_eps) f [1/s]."""
    H = hardening(taubar, tau_star)
    return K0 * gdot_p * H * (fm - f) - K0 * (gdot_p + taubar * inv_etaB + xi_eps) * f


@register_jitable
def structure_step(f, taubar, gdot_p, fm, tau_star, inv_etaB, K0, xi_eps, dt):
    """Backward-Euler step of the Table 8 structure law at fixed (taubar, gdot_p) [-].

    ``f_new = (f + dt K0 H gdot_p f_m) / (1 + dt K0 (H gdot_p + gdot_p + taubar/eta_B + xi_eps))``;
    unconditionally stable, keeps f in [0, max(f, f_m)], and its fixed point is Eq. (13) exactly.
    """
    Hg = hardening(taubar, tau_star) * gdot_p
    return (f + dt * K0 * Hg * fm) / (1.0 + dt * K0 * (Hg + gdot_p + taubar * inv_etaB + xi_eps))


# ------------------------------------------------------------------ granular flow rule (Table 8)
@register_jitable
def inertial_numbers(gdot_p, p, eta0, d, rho_s):
    """Table 8: (I, I_v, I_m) = (gdot d sqrt(rho_s/p), eta0 gdot/p, sqrt(I^2 + 2 I_v)) for p > 0."""
    I = gdot_p * d * np.sqrt(rho_s / p)
    I_v = eta0 * gdot_p / p
    return I, I_v, np.sqrt(I * I + 2.0 * I_v)


@register_jitable
def friction(I_v, I_m, phi, a, mu1, mu2, b):
    """Table 8: mu_p = mu_1 + (mu_2 - mu_1)/(1 + b/I_m) + 5/2 phi I_v/(a I_m) [-] (mu_1 at rest)."""
    Im = np.maximum(I_m, TINY)
    return mu1 + (mu2 - mu1) / (1.0 + b / Im) + 2.5 * phi * I_v / (a * Im)


@register_jitable
def phi_equilibrium(phim, a, I_m):
    """Table 8: critical-state packing phi_eq = phi_m/(1 + a I_m) [-]."""
    return phim / (1.0 + a * I_m)


@register_jitable
def dilation_angle(phi, phieq, K3):
    """Table 8: beta = K3 (phi - phi_eq) [-]."""
    return K3 * (phi - phieq)


@register_jitable
def critical_friction(phi, y, a, mu1, mu2, b):
    """Rate-independent friction at the critical state (phi = phi_eq) [-].

    There I_m = y/(a phi) with y = phi_m - phi >= 0 the jamming gap, so the mu_2 term of Table 8 is
    a constant: mu* = mu_1 + (mu_2 - mu_1) y/(y + b a phi).
    """
    return mu1 + (mu2 - mu1) * y / np.maximum(y + b * a * phi, TINY)


@register_jitable
def critical_shear_rate(taubar, phi, y, a, mu1, mu2, b, eta0, d, rho_s):
    """Plastic shear rate at the critical state (phi = phi_eq) under granular shear stress taubar.

    This is Eq. (35) (the viscous law of Eq. 1, consistent with Table 8) with grain inertia kept.
    At phi = phi_eq, f_1 = 0 and f_3 = 0 give, with the jamming gap y = max(phi_m - phi, 0) (pass
    it computed without cancellation where it is tiny), ``A gdot^2 + B gdot = taubar y^2``,
    ``A = mu* (a phi)^2 d^2 rho_s``, ``B = eta0 [2 mu* (a phi)^2 + 5/2 phi^2 y]``; multiplied through
    by y^2 it stays finite through jamming and gives gdot = 0 for y = 0 [1/s].
    """
    mu = critical_friction(phi, y, a, mu1, mu2, b)
    ap2 = (a * phi) ** 2
    A = mu * ap2 * d * d * rho_s
    B = eta0 * (2.0 * mu * ap2 + 2.5 * phi * phi * y)
    c = np.maximum(taubar, 0.0) * y * y
    return 2.0 * c / (B + np.sqrt(B * B + 4.0 * A * c))


@register_jitable
def critical_pressure(gdot_p, phi, y, a, eta0, d, rho_s):
    """Granular pressure at the critical state, f_3 = 0 with K4 = 0 [Pa], for a gap y > 0.

    p = (a phi)^2 (gdot^2 d^2 rho_s + 2 eta0 gdot) / y^2, y = phi_m - phi (Eq. 2, viscous limit).
    """
    return (a * phi) ** 2 * (gdot_p * gdot_p * d * d * rho_s + 2.0 * eta0 * gdot_p) / np.maximum(
        y * y, TINY)


# ------------------------------------------------------------------ fluid phase (Table 8)
@register_jitable
def beetstra_F(phi, Re):
    """Beetstra et al. (2007) normalised drag F(phi, Re) [-] (F -> 1 as phi, Re -> 0).

    F = 10 phi/(1-phi)^2 + (1-phi)^2 (1 + 1.5 sqrt(phi)) + F_1(Re_s), with Re_s = (1 - phi) Re and
    F_1 = 0.413 Re_s/(24 (1-phi)^2) (1/(1-phi) + 3 phi (1-phi) + 8.4 Re_s^-0.343)
          / (1 + 10^(3 phi) Re_s^(-(1 + 4 phi)/2)).
    """
    n = 1.0 - phi
    F0 = 10.0 * phi / (n * n) + n * n * (1.0 + 1.5 * np.sqrt(phi))
    Res = np.maximum(n * Re, 1e-12)
    F1 = (0.413 * Res / (24.0 * n * n) * (1.0 / n + 3.0 * phi * n + 8.4 * Res ** -0.343)
          / (1.0 + 10.0 ** (3.0 * phi) * Res ** (-(1.0 + 4.0 * phi) / 2.0)))
    return F0 + F1


@register_jitable
def drag_coefficient(phi, Re, eta0, d):
    """Table 8 Darcy drag coefficient C = 18 phi (1 - phi) eta0 F(phi, Re)/d^2 [Pa s/m^2]: the
    inter-phase force per volume is f_d = C (v_s - v_f); Re = rho_f |v_s - v_f| d / eta0."""
    return 18.0 * phi * (1.0 - phi) * eta0 * beetstra_F(phi, Re) / (d * d)


@register_jitable
def fluid_viscosity(phi, eta0):
    """Table 8 fluid-phase viscosity eta0 (1 + 5/2 phi) [Pa s] (Einstein's correction)."""
    return eta0 * (1.0 + 2.5 * phi)


@register_jitable
def pore_pressure(rho_f, rho_0f, kappa):
    """Table 8 pore pressure kappa ln(rho_f/rho_0f) [Pa] from the true fluid density [kg/m^3]."""
    return kappa * vecmath.log(rho_f / rho_0f)
