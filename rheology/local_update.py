"""The Table 8 granular law as an implicit local update over arrays of material points.

One time step dt at each point, given the stress sigma_n (3x3), the granular velocity gradient
L = grad v_s (3x3, so plane strain and axisymmetry both fit: L_zz = 0 or L_thth = v_r/r), phi and
f_n:

1. Elastic trial (Jaumann): sigma* = sigma_n + dt [2G D' + K tr(D) 1 + W sigma_n - sigma_n W].
   tau* = sqrt(s*:s*/2), p* = -tr(sigma*)/3.
2. The plastic correction is radial in the deviator and volumetric in the pressure:
   taubar = tau* - G dt gdot_p,  p = p* + K dt (beta gdot_p + xi_1 + xi_2),
   with gdot_p >= 0, xi_1 >= 0, xi_2 <= 0 chosen by the yield rules f_1, f_2, f_3 of Table 8.
   The cases, tried in this order:

   - separation (p* + (K/G) tau* K3 phi <= 0): the skeleton is stress free, f_2 = 0
     (xi_1 = -p*/(K dt), beta = 0, gdot_p = tau*/(G dt)). The bound is the largest pressure
     dilatancy can make, beta -> K3 phi at gdot_p -> tau*/(G dt); above it a flowing solution
     with p > 0 exists for any p* (the limit p* -> 0+: a stress-free point that is sheared flows
     with the critical-state pressure it builds by dilatancy, Boyer, Guazzelli & Pouliquen 2011),
     and it tends to the separated one at the bound: the update is continuous in p*.
   - shear flow + compaction (phi < phi_m): f_1 = f_3 = 0. With K4 = 0, f_3 = 0 is exactly
     phi = phi_eq (beta = 0) and p = P3(gdot_p), so f_1 = 0 is a quadratic in gdot_p
     (closed form); valid when P3 <= p* (xi_2 <= 0).
   - elastic (phi >= phi_m and f_1(sigma*) <= 0): gdot_p = 0. With ``rules = "mpm_3d"`` (the
     author's code, aaronbaumgarten/mpm_3d ``cornstarch.cpp``) also below jamming:
     p* >= 0 and tau* <= (mu_1 + K3 (phi - phi_m)) p* stays elastic, tried before compaction;
     Table 8's f_3 <= 0 needs gdot_p > 0 at any p > 0 below jamming (``rules = "table8"``, the
     default). That is the only difference between the two (a flowing point never meets the cone:
     mu_p + beta >= mu_1 on the yield surface); the cone is a discontinuity of the mpm_3d
     update below jamming (p jumps from p* to the flowing point's pressure across it).
   - dilatant shear flow (f_1 = 0, xi_2 = 0): for a given beta, I_m follows from
     phi_eq = phi - beta/K3, then p I_m^2 = rho_s d^2 gdot^2 + 2 eta0 gdot with
     p = p* + K dt beta gdot is a quadratic with one positive root gdot(beta); the remaining
     equation R(beta) = tau* - G dt gdot - (mu_p + beta) p = 0 is bracketed on [beta_lo, K3 phi)
     (R(beta_lo) > 0 whenever this case applies, R -> -inf as I_m -> inf). The solve
     (:func:`_dilatant_flow`): a start from Newton on the pair (beta, gdot) (:func:`_newton_2d`;
     below jamming from the compaction estimates, jammed from the previous step's plastic rate
     when the caller keeps it, a warm start), a safeguarded Newton on R(beta) with Brent's
     stopping test, else the bracket and Brent's method; where gdot(beta) is too steep to
     resolve (the trial pressure a vanishing part of the final one) gdot is the bracketed
     variable, and for p* <= 0 :func:`_dilatant_tension` solves without cancellation up to the
     separation bound. A point that still misses the yield surface is FAILED. The tolerance is
     that of the bracket-only solve (``newton=False``, kept as the reference): the Newton path
     changes the work (residual evaluations per flowing point: ~1 instead of 5-12 in MPM
     shear), not the answer beyond the convergence test.

3. The structure takes a backward-Euler step with the new (taubar, gdot_p) (staggered, first order):
   f_{n+1} = (f_n + dt K0 H gdot f_m)/(1 + dt K0 (H gdot + gdot + taubar/eta_B + xi_eps)),
   whose fixed point is Eq. (13) exactly. phi_m and a use f_n.

The point kernel :func:`update_point` (numba, the laws of :mod:`rheology.laws` written once):
the elastic trial, :func:`_correct` (step 2), step 3. :func:`update_block` runs the same update on
a block of points whose trial stress the caller gives as a structure-of-arrays (rows xx, yy, zz,
xy, xz, yz), in branch-free SIMD stages (closed-form cases, three Newton steps on (beta, gdot_p)
with update_point's convergence test, two more and the test again on the points left unconverged,
packed, 1/eta_B, the structure step); a point they do not finish goes through :func:`_correct`.
:func:`update_points` loops blocks over (N, 3, 3) arrays in parallel (:func:`local_update`, the
validated numpy front end, calls it); ``mpm2d``'s suspension kernel calls update_block,
``shear1d`` and ``rheometer`` call update_point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from . import laws
from runkit.params import check_range
from .materials import KERNEL_FIELDS, Material, get_material
from .numba_cache import guard
from .roots import brent

guard(__file__)
_jit = nb.njit(cache=True, error_model="numpy")

#: Columns of the ``out`` array written by :func:`update_point`.
OUT_FIELDS = ("f", "shear_rate_p", "xi1", "xi2", "mu_p", "I", "I_v", "I_m", "beta", "phi_eq",
              "taubar", "pressure", "case", "iterations")
NOUT = len(OUT_FIELDS)
#: Case codes (column ``case``).
ELASTIC, SEPARATED, SHEAR_FLOW, COMPACTION, FAILED = 0, 1, 2, 3, -1
CASE_NAMES = {ELASTIC: "elastic", SEPARATED: "separated", SHEAR_FLOW: "shear flow",
              COMPACTION: "shear flow + compaction", FAILED: "failed"}
_P = {name: i for i, name in enumerate(KERNEL_FIELDS)}
#: rheology.roots.brent's relative bracket tolerance and evaluation limit
_XTOL = 1e-14
_MAXIT = 200


@_jit
def _dilatant_rate(beta, phi, phim, a, p_tr, Kdt, eta0, rd2, K3):
    """gdot_p(beta), p(beta), I_m(beta) on the dilatant branch (see module docstring)."""
    x = phi - beta / K3                       # phi_eq
    Im = (phim - x) / (a * x)
    Im2 = Im * Im
    bq = 2.0 * eta0 - Kdt * beta * Im2
    cq = p_tr * Im2
    if bq > 0.0:
        g = 2.0 * cq / (bq + np.sqrt(bq * bq + 4.0 * rd2 * cq))
    elif rd2 > 0.0:
        g = (-bq + np.sqrt(bq * bq + 4.0 * rd2 * cq)) / (2.0 * rd2)
    else:
        g = np.inf
    return g, p_tr + Kdt * beta * g, Im


@_jit
def _beta_of_rate(g, phi, phim, a, p_tr, Kdt, eta0, rd2, K3, lo, hi):
    """beta on the dilatant branch for a given gdot_p: root of the decreasing polynomial
    F(beta) = (rd2 g^2 + 2 eta0 g)(a x)^2 - (phi_m - x)^2 (p* + K dt beta g), x = phi - beta/K3,
    on [lo, hi] with F(lo) >= 0 (safeguarded Newton)."""
    Ag = rd2 * g * g + 2.0 * eta0 * g
    beta = lo
    for _ in range(200):
        x = phi - beta / K3
        w = phim - x
        pb = p_tr + Kdt * beta * g
        F = Ag * (a * x) ** 2 - w * w * pb
        if F > 0.0:
            lo = beta
        else:
            hi = beta
        if F == 0.0 or hi - lo <= 4e-16 * hi:
            break
        dF = -2.0 * Ag * a * a * x / K3 - 2.0 * w * pb / K3 - w * w * Kdt * g
        nb = beta - F / dF
        if abs(nb - beta) <= 1e-15 * beta:     # converged (as in _tension_state)
            if lo < nb < hi:
                beta = nb
            break
        beta = nb if lo < nb < hi else 0.5 * (lo + hi)
    return beta


@_jit
def _residual(x, mode, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2, b, blo, bhi):
    """R = tau* - G dt gdot - (mu_p + beta) p on the dilatant branch, parametrised by beta (mode 0,
    closed form, fast), by gdot (mode 1, inner solve for beta, well conditioned when p* << p) or,
    for p* <= 0, by h = gdot - g_min (mode 2, :func:`_dilatant_tension`)."""
    if mode == 0:
        beta = x
        g, p, Im = _dilatant_rate(beta, phi, phim, a, p_tr, Kdt, eta0, rd2, K3)
        if not np.isfinite(g):
            return -np.inf
    elif mode == 2:                      # x = h, blo = g_min, bhi = h_max (_dilatant_tension)
        xe, p, g = _tension_state(x, blo, phi, phim, a, Kdt, eta0, rd2, K3)
        if not p > 0.0:                  # p below the smallest double: the limit p -> 0+
            return Gdt * (bhi - x)
        Iv = eta0 * g / p
        Im = (phim - xe) / (a * xe)
        return Gdt * (bhi - x) - (laws.friction(Iv, Im, phi, a, mu1, mu2, b)
                                  + (p - p_tr) / (Kdt * g)) * p
    else:
        g = x
        beta = _beta_of_rate(g, phi, phim, a, p_tr, Kdt, eta0, rd2, K3, blo, bhi)
        p = p_tr + Kdt * beta * g
        xe = phi - beta / K3
        Im = (phim - xe) / (a * xe)
    Iv = eta0 * g / p
    return tau_tr - Gdt * g - (laws.friction(Iv, Im, phi, a, mu1, mu2, b) + beta) * p


@_jit
def _residual_slope(beta, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2, b):
    """R(beta) of mode 0 (the same arithmetic as :func:`_residual`) with what its slope needs.

    Returns (R, gdot, p, I_m, x, sqrt(disc), I_v, mu_p); :func:`_slope` gives dR/dbeta from them.
    """
    x = phi - beta / K3
    Im = (phim - x) / (a * x)
    Im2 = Im * Im
    bq = 2.0 * eta0 - Kdt * beta * Im2
    cq = p_tr * Im2
    sq = np.sqrt(bq * bq + 4.0 * rd2 * cq)
    if bq > 0.0:
        g = 2.0 * cq / (bq + sq)
    elif rd2 > 0.0:
        g = (-bq + sq) / (2.0 * rd2)
    else:
        return -np.inf, np.inf, np.inf, Im, x, sq, np.inf, np.inf
    p = p_tr + Kdt * beta * g
    Iv = eta0 * g / p
    mu = laws.friction(Iv, Im, phi, a, mu1, mu2, b)
    return tau_tr - Gdt * g - (mu + beta) * p, g, p, Im, x, sq, Iv, mu


@_jit
def _slope(beta, g, p, Im, x, sq, Iv, mu, phi, phim, a, Gdt, Kdt, eta0, K3, mu1, mu2, b):
    """dR/dbeta for Newton. With x = phi - beta/K3, I_m = (phi_m - x)/(a x),
    dI_m/dbeta = phi_m/(a x^2 K3); gdot is the positive root of rd2 g^2 + bq g - p* I_m^2 = 0
    (bq = 2 eta0 - K dt beta I_m^2), so dg/dbeta = (K dt I_m^2 g + 2 p I_m dI_m)/sqrt(disc);
    p = p* + K dt beta g, I_v = eta0 g/p and mu_p(I_v, I_m) of Table 8 follow by the chain rule."""
    dIm = phim / (a * x * x * K3)
    dg = (Kdt * Im * Im * g + 2.0 * p * Im * dIm) / sq
    dp = Kdt * (g + beta * dg)
    Imc = max(Im, laws.TINY)
    dIv = eta0 * (dg * p - g * dp) / (p * p)
    dmu = ((mu2 - mu1) * b / ((Imc + b) * (Imc + b)) * dIm
           + 2.5 * phi / a * (dIv / Imc - Iv * dIm / (Imc * Imc)))
    return -Gdt * dg - (dmu + 1.0) * p - (mu + beta) * dp


#: Newton iterations tried (2-D start, then 1-D) before the bracket takes over.
_NEWTON2D_MAX = 8
_NEWTON_MAX = 6


@nb.njit(cache=True, error_model="numpy", inline="always")
def _critical_state(tau_tr, phi, y, a, Gdt, mu1, mu2, b, eta0, rho_s, d):
    """Shear flow + compaction at the critical state (beta = 0, phi = phi_eq, K4 = 0): the plastic
    rate gdot_c for which f_1 = 0 under the trial stress tau* (A g^2 + B g = tau* y^2, with the
    elastic relaxation G dt y^2 in B) and the pressure p_c = P3(gdot_c) (laws.critical_pressure);
    y = phi_m - phi > 0. Returns (gdot_c, p_c). (Scalars, not the parameter array: loads from an
    array inside update_block's loops would not be hoisted, and the loop would not vectorise.)"""
    ap2 = (a * phi) ** 2
    mus = laws.critical_friction(phi, y, a, mu1, mu2, b)
    A = mus * ap2 * rho_s * d * d
    B = eta0 * (2.0 * mus * ap2 + 2.5 * phi * phi * y) + Gdt * y * y
    c = tau_tr * y * y
    gc = 2.0 * c / (B + np.sqrt(B * B + 4.0 * A * c))
    return gc, laws.critical_pressure(gc, phi, y, a, eta0, d, rho_s)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _im_terms(beta, phi, phim, a, b, eta0, iK3):
    """The dilatant branch's I_m terms at beta from one reciprocal (shared by the Newton step and
    update_block's test): x = phi_eq = phi - beta iK3, w = phi_m - x, a x, wb = w + b a x,
    q = 1/(a x w wb), 1/(a x) = w wb q, I_m = w/(a x) and V = 5/2 phi eta0/(a I_m)."""
    x = phi - beta * iK3
    w = phim - x
    ax = a * x
    wb = w + b * ax
    q = 1.0 / (ax * w * wb)
    iax = w * wb * q
    return x, w, ax, wb, q, iax, w * iax, 2.5 * phi * eta0 * x * ax * wb * q


@nb.njit(cache=True, error_model="numpy", inline="always")
def _newton_2d_step(beta, g, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, iK3, mu1, mu2, b):
    """One Newton step (d beta, d gdot_p) on the pair F1, F2 of :func:`_newton_2d` at (beta, g);
    iK3 = 1/K3. Branch-free, so that update_block's loop over a block becomes SIMD code; two
    divisions (1/(a x), I_m, 1/I_m and 1/(I_m + b) from one reciprocal of their product)."""
    x, w, ax, wb, q, iax, Im, V = _im_terms(beta, phi, phim, a, b, eta0, iK3)
    ib = ax * ax * w * q                     # 1/(I_m + b)
    p = p_tr + Kdt * beta * g
    Ag = rd2 * g * g + 2.0 * eta0 * g
    F1 = p * w * w - Ag * ax * ax
    F1b = Kdt * g * w * w + 2.0 * (p * w + Ag * a * ax) * iK3
    F1g = Kdt * beta * w * w - (2.0 * rd2 * g + 2.0 * eta0) * ax * ax
    dIm = phim * a * iax * iax * iK3
    M = mu1 + beta + (mu2 - mu1) * Im * ib
    iIm = ax * ax * wb * q                   # 1/I_m
    F2 = tau_tr - Gdt * g - M * p - V * g
    F2b = -(1.0 + (mu2 - mu1) * b * ib * ib * dIm) * p - M * Kdt * g + V * g * dIm * iIm
    F2g = -Gdt - M * Kdt * beta - V
    idet = 1.0 / (F1b * F2g - F1g * F2b)
    return (F1g * F2 - F1 * F2g) * idet, (F1 * F2b - F1b * F2) * idet


@_jit
def _newton_2d(beta, g, beta_lo, beta_top, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3,
               mu1, mu2, b):
    """Starting point of the dilatant solve: Newton on the pair (beta, gdot_p) of smooth equations

    F1 = p (phi_m - x)^2 - (rd2 g^2 + 2 eta0 g)(a x)^2 = 0   (I_m of phi_eq = x, times (a x)^2)
    F2 = tau* - G dt g - (mu_1 + beta + (mu_2 - mu_1) I_m/(I_m + b)) p - 5/2 phi eta0 g/(a I_m) = 0
         (the yield condition f_1 = 0: F2 = R when g = gdot(beta))

    with x = phi - beta/K3, p = p* + K dt beta g. Unlike R(beta), which has a pole where
    K dt beta I_m^2 -> 2 eta0 (the trial pressure a vanishing part of the final one), both are
    polynomial-like, so a warm start in g (the previous step's rate) converges quadratically.
    Returns beta, or a value <= beta_lo if an iterate leaves (beta_lo, beta_top) x (0, inf) or
    does not settle (the caller then starts elsewhere; the result is only a starting point).
    """
    iK3 = 1.0 / K3
    r_prev = np.inf
    for _ in range(_NEWTON2D_MAX):
        db, dg = _newton_2d_step(beta, g, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, iK3,
                                 mu1, mu2, b)
        bn, gn = beta + db, g + dg
        if not (beta_lo < bn < beta_top and gn > 0.0 and gn < np.inf):
            return beta_lo
        beta, g = bn, gn
        r = max(abs(db) / bn, abs(dg) / gn)
        # quadratic convergence: the error left after this step is ~ r^3 / r_prev^2
        if r <= 1e-8 or (r <= 1e-4 and r * r * r <= 1e-16 * r_prev * r_prev):
            return beta
        r_prev = r
    return beta_lo




@_jit
def _dilatant_flow(beta_lo, r_lo, beta_guess, beta_start, phi, phim, a, p_tr, tau_tr, Gdt, Kdt,
                   eta0, rd2, K3, mu1, mu2, b, newton, g_warm=-1.0):
    """Dilatant shear flow (f_1 = 0, xi_2 = 0): returns (beta, gdot_p, p, I_m, evaluations).

    1. Safeguarded Newton in beta from ``beta_start`` (the warm start; skipped when it is outside
       (beta_lo, beta_max) or ``newton`` is False): every iterate narrows the bracket
       [lo, hi] (R(lo) > 0 > R(hi)); it stops at the same test as Brent's (|R| at the roundoff
       floor, or a step below 1e-14 beta) and is accepted by the same convergence check.
       A step that leaves the bracket, a non-negative slope or a non-finite value hands over to:
    2. the bracket: expansion from lo (steps from ``beta_guess``) until R < 0, then Brent's method;
    3. if that leaves a residual (the trial pressure is a vanishing part of the final one, so
       gdot(beta) is too steep to resolve), again with gdot as the bracketed variable.
    ``r_lo`` = R(beta_lo), or NaN if not evaluated yet. evaluations: residual evaluations made
    here (a Newton iterate, R with its slope, counts one); < 0 means every stage failed.
    At p* <= 0: :func:`_dilatant_tension`, from ``g_warm`` (the previous gdot_p) if positive.
    """
    beta_max = K3 * phi
    beta_top = beta_lo + (beta_max - beta_lo) * (1.0 - 1e-15)
    # converged: |R| small against the final stress, above the roundoff floor of tau* - G dt gdot
    floor = 2e-15 * (tau_tr + mu1 * abs(p_tr))
    n = 0
    lo, hi, r_hi = beta_lo, beta_top, 0.0
    hi_known = False
    if p_tr <= 0.0:
        return _dilatant_tension(phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2,
                                 b, floor, g_warm if newton else -1.0)
    if newton and beta_lo < beta_start < beta_top:
        x = beta_start
        for _ in range(_NEWTON_MAX):
            R, g, p, Im, xe, sq, Iv, mu = _residual_slope(x, phi, phim, a, p_tr, tau_tr, Gdt, Kdt,
                                                          eta0, rd2, K3, mu1, mu2, b)
            n += 1
            if abs(R) <= floor:        # the usual exit: the start was converged already
                return x, g, p, Im, n
            if not np.isfinite(R):
                if R < 0.0:                  # gdot(beta) = inf: beyond the root
                    hi, r_hi, hi_known = x, R, True
                break
            if R > 0.0:
                lo, r_lo = x, R
            else:
                hi, r_hi, hi_known = x, R, True
            dR = _slope(x, g, p, Im, xe, sq, Iv, mu, phi, phim, a, Gdt, Kdt, eta0, K3, mu1, mu2, b)
            step = R / dR
            if abs(step) <= 1e-14 * abs(x):
                if abs(R) <= 1e-12 * (tau_tr - Gdt * g + mu1 * p) + floor:
                    return x, g, p, Im, n
                break
            if not (dR < 0.0 and np.isfinite(dR)):
                break
            xn = x - step
            if not (lo < xn < hi):
                break
            x = xn
    if not (r_lo == r_lo):                                   # R(beta_lo) not evaluated yet
        r_lo = _residual(beta_lo, 0, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1,
                         mu2, b, 0.0, 0.0)
        n += 1
    if hi_known and not np.isfinite(r_hi):
        hi_known = False
    if not hi_known:
        step = max(1e-14 * beta_max, 1e-8 * lo, 2.0 * beta_guess)
        hi = min(lo + step, beta_top)
        while True:
            r_hi = _residual(hi, 0, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2,
                             b, 0.0, 0.0)
            n += 1
            if r_hi < 0.0 or hi >= beta_top:
                break
            lo, r_lo = hi, r_hi
            step *= 10.0
            hi = min(lo + step, beta_top)
    if r_hi < 0.0:
        beta, r, it = brent(_residual, (0, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3,
                                        mu1, mu2, b, 0.0, 0.0), lo, hi, r_lo, r_hi, _XTOL,
                            1e-300, floor, _MAXIT)
        g, p, Im = _dilatant_rate(beta, phi, phim, a, p_tr, Kdt, eta0, rd2, K3)
        n += max(it, 0)
        if it >= 0 and abs(r) <= 1e-12 * (tau_tr - Gdt * g + mu1 * p) + floor:
            return beta, g, p, Im, n
    # fallback: gdot on [gdot(beta_lo), tau*/(G dt)], where R > 0 and R < 0
    g_lo, _, _ = _dilatant_rate(beta_lo, phi, phim, a, p_tr, Kdt, eta0, rd2, K3)
    g_hi = tau_tr / Gdt
    r0 = _residual(g_lo, 1, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2, b,
                   beta_lo, beta_top)
    r1 = _residual(g_hi, 1, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2, b,
                   beta_lo, beta_top)
    if not (r0 > 0.0 and r1 < 0.0):
        return beta_lo, 0.0, p_tr, 0.0, -1
    g, r, it = brent(_residual, (1, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2,
                                 b, beta_lo, beta_top), g_lo, g_hi, r0, r1, _XTOL, 1e-300,
                     floor, _MAXIT)
    beta = _beta_of_rate(g, phi, phim, a, p_tr, Kdt, eta0, rd2, K3, beta_lo, beta_top)
    p = p_tr + Kdt * beta * g
    xe = phi - beta / K3
    n += max(it, 0) + 2
    if it < 0 or abs(r) > 1e-10 * (tau_tr - Gdt * g + mu1 * p) + 10.0 * floor:
        return beta, g, p, (phim - xe) / (a * xe), -1
    return beta, g, p, (phim - xe) / (a * xe), n


@_jit
def _tension_state(h, g_min, phi, phim, a, Kdt, eta0, rd2, K3):
    """The dilatant branch at p* <= 0 for gdot_p = g_min + h, g_min = -p*/(K dt K3 phi):
    returns (x, p, gdot_p) with x = phi_eq = phi - beta/K3.

    There p* + K dt beta gdot_p = K dt K3 (phi h - x gdot_p), so the I_m relation
    F(x) = A_g (a x)^2 - (phi_m - x)^2 K dt K3 (phi h - x gdot_p) = 0, A_g = rd2 g^2 + 2 eta0 g,
    is increasing on [0, min(phi_m, phi h/gdot_p)] from F(0) < 0 to F > 0: one root, found by a
    safeguarded Newton from the root of its small-x quadratic. p = A_g (a x)^2/(phi_m - x)^2 then
    follows from the I_m relation without the cancellation of p* + K dt beta gdot_p (p can be
    a vanishing part of |p*| near separation), and beta = (p - p*)/(K dt gdot_p), a sum of
    positive terms, without that of K3 (phi - x) (beta can be a vanishing part of K3 phi).
    """
    g = g_min + h
    Ag = rd2 * g * g + 2.0 * eta0 * g
    A2 = Ag * a * a
    kg = Kdt * K3 * g
    c = Kdt * K3 * phi * h
    lo, hi = 0.0, min(phim, phi * h / g)
    B, C = phim * phim * kg, phim * phim * c
    x = 2.0 * C / (B + np.sqrt(B * B + 4.0 * A2 * C))
    if not lo < x < hi:
        x = 0.5 * hi
    for _ in range(200):
        w = phim - x
        lin = c - kg * x
        F = A2 * x * x - w * w * lin
        if F > 0.0:
            hi = x
        else:
            lo = x
        if F == 0.0 or hi - lo <= 4e-16 * hi:
            break
        xn = x - F / (2.0 * A2 * x + 2.0 * w * lin + w * w * kg)
        # converged: tested before the bracket, since a converged step can land on the end
        # the iterate itself has just become (bisecting from there would take ~40 more steps)
        if abs(xn - x) <= 1e-15 * x:
            if lo < xn < hi:
                x = xn
            break
        x = xn if lo < xn < hi else 0.5 * (lo + hi)
    w = phim - x
    return x, Ag * (a * x) ** 2 / (w * w), g


@_jit
def _tension_newton(h, g_min, h_max, phi, phim, a, p_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2, b):
    """Newton on the pair (x, h) of :func:`_dilatant_tension` from h (a warm start): the
    I_m relation F1 = A_g (a x)^2 - (phi_m - x)^2 K dt K3 (phi h - x gdot_p) = 0 of
    :func:`_tension_state` and F2 = G dt (h_max - h) - (mu_p + beta) p = 0 together, with
    p = A_g (a x)^2/(phi_m - x)^2 and beta = (p - p*)/(K dt gdot_p), so that no step solves
    for x alone (each of Brent's evaluations does). (mu_p + beta) p = mu_1 p + (mu_2 - mu_1) U p
    + V + beta p, U = w/(w + b a x), V = 5/2 phi eta0 gdot_p x/w (w = phi_m - x). Returns
    (h, iterations) once a step is below 1e-14 h (Brent's bracket exit), or h = -1 if an
    iterate leaves (0, phi_m) x (0, h_max) or does not settle (the caller then solves by the
    bracket)."""
    kK = Kdt * K3
    x = _tension_state(h, g_min, phi, phim, a, Kdt, eta0, rd2, K3)[0]
    c = 2.5 * phi * eta0
    for it in range(1, _NEWTON_MAX + 1):
        g = g_min + h
        A = rd2 * g * g + 2.0 * eta0 * g
        Ah = 2.0 * rd2 * g + 2.0 * eta0
        w = phim - x
        lin = phi * h - x * g
        F1 = A * a * a * x * x - w * w * kK * lin
        F1x = 2.0 * A * a * a * x + 2.0 * w * kK * lin + w * w * kK * g
        F1h = Ah * a * a * x * x - w * w * kK * (phi - x)
        p = A * a * a * x * x / (w * w)
        px = 2.0 * A * a * a * x * phim / (w * w * w)
        ph = Ah * a * a * x * x / (w * w)
        beta = (p - p_tr) / (Kdt * g)
        bx = px / (Kdt * g)
        bh = ph / (Kdt * g) - beta / g
        q = w + b * a * x
        U = w / q
        Ux = -b * a * phim / (q * q)
        V = c * g * x / w
        M = mu1 + (mu2 - mu1) * U + beta
        T = M * p + V
        Tx = M * px + ((mu2 - mu1) * Ux + bx) * p + c * g * phim / (w * w)
        Th = M * ph + bh * p + c * x / w
        F2 = Gdt * (h_max - h) - T
        F2x, F2h = -Tx, -Gdt - Th
        idet = 1.0 / (F1x * F2h - F1h * F2x)
        dx = (F1h * F2 - F1 * F2h) * idet
        dh = (F2x * F1 - F2 * F1x) * idet
        xn, hn = x + dx, h + dh
        if not (0.0 < xn < phim and 0.0 < hn < h_max):
            return -1.0, it
        x, h = xn, hn
        if abs(dh) <= 1e-14 * h:
            return h, it
    return -1.0, _NEWTON_MAX


@_jit
def _dilatant_tension(phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2, b, floor,
                      g_warm=-1.0):
    """The dilatant solve at p* <= 0, p* + (K/G) tau* K3 phi > 0: returns what
    :func:`_dilatant_flow` returns.

    For p* <= 0, gdot_p(beta) is not single-valued, but beta(gdot_p) is (:func:`_tension_state`);
    a flowing solution needs p* + K dt beta gdot_p > 0, i.e. gdot_p > g_min = -p*/(K dt K3 phi).
    With h = gdot_p - g_min, R(h) = G dt (h_max - h) - (mu_p + beta) p (h_max = tau*/(G dt) -
    g_min) tends to G dt h_max > 0 as h -> 0 (beta -> K3 phi, I_m -> inf, p -> 0 and
    (mu_p + beta) p -> 0) and is negative at h_max: Brent's method on (0, h_max) (mode 2 of
    :func:`_residual`). Every quantity is formed without cancellation, so the solve is resolved
    up to the separation boundary, where the solution tends to the separated one
    (taubar <= G dt h_max, p <= taubar/mu_1).

    ``g_warm`` > g_min (the point's previous gdot_p): :func:`_tension_newton` from it first,
    stopped where Brent's bracket would be (a step below 1e-14 h) and accepted by the same
    final test as Brent's result; otherwise, or if it fails, the bracket.
    """
    g_min = -p_tr / (Kdt * K3 * phi)
    h_max = (p_tr + Kdt * tau_tr / Gdt * K3 * phi) / (Kdt * K3 * phi)   # > 0: not separated
    if 0.0 < g_warm - g_min < h_max:
        h, it = _tension_newton(g_warm - g_min, g_min, h_max, phi, phim, a, p_tr, Gdt, Kdt,
                                eta0, rd2, K3, mu1, mu2, b)
        if h > 0.0:
            x, p, g = _tension_state(h, g_min, phi, phim, a, Kdt, eta0, rd2, K3)
            # R of _residual's mode 2 at this state (without solving for x again)
            r = Gdt * (h_max - h) - (laws.friction(eta0 * g / p, (phim - x) / (a * x), phi, a, mu1,
                                                   mu2, b) + (p - p_tr) / (Kdt * g)) * p
            if p > 0.0 and abs(r) <= 1e-10 * (Gdt * (h_max - h) + mu1 * p) + 10.0 * floor:
                return (p - p_tr) / (Kdt * g), g, p, (phim - x) / (a * x), it + 1
    r1 = _residual(h_max, 2, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2, b,
                   g_min, h_max)
    if not r1 < 0.0:
        return K3 * phi, tau_tr / Gdt, 0.0, np.inf, -1
    h, r, it = brent(_residual, (2, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2,
                                 b, g_min, h_max), 0.0, h_max, Gdt * h_max, r1, _XTOL,
                     1e-300, floor, _MAXIT)
    x, p, g = _tension_state(h, g_min, phi, phim, a, Kdt, eta0, rd2, K3)
    n = max(it, 0) + 1
    if it < 0 or not p > 0.0 or abs(r) > 1e-10 * (Gdt * (h_max - h) + mu1 * p) + 10.0 * floor:
        n = -1
    return (p - p_tr) / (Kdt * g), g, p, (phim - x) / (a * x), n


@nb.njit(cache=True, error_model="numpy", inline="always")
def jaumann_elastic(s, L, dt, G, K):
    """Jaumann elastic predictor on scalars: s + dt [2G D' + K tr(D) 1 + W s - s W].

    ``s`` and ``L`` are 9-tuples (row-major 3 x 3: stress [Pa], velocity gradient [1/s]); returns
    the new stress as a 9-tuple. Written out component by component
    (W = [[0, w01, w02], [-w01, 0, w12], [-w02, -w12, 0]]) and inlined, so that a caller keeps the
    point in registers (no scratch arrays): this is the MPM's linear-elastic update, and the
    trial step of every Table 8 update (:func:`elastic_trial`).
    """
    d0, d1, d2 = L[0], L[4], L[8]
    e01, e02, e12 = 0.5 * (L[1] + L[3]), 0.5 * (L[2] + L[6]), 0.5 * (L[5] + L[7])
    w01, w02, w12 = 0.5 * (L[1] - L[3]), 0.5 * (L[2] - L[6]), 0.5 * (L[5] - L[7])
    lam = (K - 2.0 * G / 3.0) * (d0 + d1 + d2)
    G2 = 2.0 * G
    s00, s01, s02, s10, s11, s12, s20, s21, s22 = s
    return (s00 + dt * (G2 * d0 + lam + w01 * (s10 + s01) + w02 * (s20 + s02)),
            s01 + dt * (G2 * e01 + w01 * (s11 - s00) + w02 * s21 + s02 * w12),
            s02 + dt * (G2 * e02 + w01 * s12 + w02 * (s22 - s00) - s01 * w12),
            s10 + dt * (G2 * e01 - w01 * s00 + w12 * s20 + s11 * w01 + s12 * w02),
            s11 + dt * (G2 * d1 + lam - w01 * (s01 + s10) + w12 * (s21 + s12)),
            s12 + dt * (G2 * e12 - w01 * s02 + w12 * (s22 - s11) - s10 * w02),
            s20 + dt * (G2 * e02 - w02 * s00 - w12 * s10 + s21 * w01 + s22 * w02),
            s21 + dt * (G2 * e12 - w02 * s01 - w12 * s11 - s20 * w01 + s22 * w12),
            s22 + dt * (G2 * d2 + lam - w02 * (s02 + s20) - w12 * (s12 + s21)))


@nb.njit(cache=True, error_model="numpy", inline="always")
def jaumann_elastic_plane(s00, s01, s11, s22, l00, l01, l10, l11, l22, dt, G, K):
    """:func:`jaumann_elastic` of a symmetric stress with no out-of-plane shear
    (sigma_02 = sigma_12 = 0) under a gradient with none (L_02 = L_12 = L_20 = L_21 = 0):
    plane strain (L_22 = 0) and axisymmetry without swirl (index 2 = theta, L_22 = v_r/r).

    Those components stay exactly zero and sigma stays symmetric, so only (s00, s01, s11, s22)
    [Pa] change: returns them. Same terms as :func:`jaumann_elastic` with W = w01 (e_01 - e_10)."""
    e01, w01 = 0.5 * (l01 + l10), 0.5 * (l01 - l10)
    lam = (K - 2.0 * G / 3.0) * (l00 + l11 + l22)
    G2 = 2.0 * G
    rot = 2.0 * w01 * s01
    return (s00 + dt * (G2 * l00 + lam + rot),
            s01 + dt * (G2 * e01 + w01 * (s11 - s00)),
            s11 + dt * (G2 * l11 + lam - rot),
            s22 + dt * (G2 * l22 + lam))


@_jit
def elastic_trial(sig, L, dt, G, K, out):
    """Jaumann elastic predictor sigma + dt [2G D' + K tr(D) 1 + W sigma - sigma W] into ``out``
    (sig, L, out: 3 x 3 arrays; :func:`jaumann_elastic` on their entries)."""
    r = jaumann_elastic((sig[0, 0], sig[0, 1], sig[0, 2], sig[1, 0], sig[1, 1], sig[1, 2],
                         sig[2, 0], sig[2, 1], sig[2, 2]),
                        (L[0, 0], L[0, 1], L[0, 2], L[1, 0], L[1, 1], L[1, 2],
                         L[2, 0], L[2, 1], L[2, 2]), dt, G, K)
    out[0, 0], out[0, 1], out[0, 2] = r[0], r[1], r[2]
    out[1, 0], out[1, 1], out[1, 2] = r[3], r[4], r[5]
    out[2, 0], out[2, 1], out[2, 2] = r[6], r[7], r[8]


@nb.njit(cache=True, error_model="numpy", inline="always")
def _structure_tail(f, phi, g, tau_tr, Gdt, P, dt, invB, sep):
    """What follows the plastic correction: the equivalent shear stress taubar = max(tau* - G dt
    gdot_p, 0) (0 for a separated point, ``sep``), the deviator's scale factor taubar/tau* and
    the structure's backward-Euler step; ``invB`` = 1/eta_B(phi) (laws.inv_eta_B). Branch-free
    (selects), so a block runs it for all its points as SIMD. Returns (taubar, scale, f_new)."""
    phi_c, phi_j, tau_star, Delta, xi_eps, K0 = P[0], P[1], P[7], P[13], P[14], P[15]
    taubar = 0.0 if sep else max(tau_tr - Gdt * g, 0.0)
    scale = taubar / tau_tr if tau_tr > 0.0 else 0.0
    fm = laws.f_max(phi, phi_c, phi_j, Delta)
    return taubar, scale, laws.structure_step(f, taubar, g, fm, tau_star, invB, K0, xi_eps, dt)


@nb.njit(cache=True, error_model="numpy", inline="always")
def _flow_outputs(phi, phim, a, g, p, Im, P):
    """The diagnostic outputs mu_p, I, I_v (inf where p = 0, e.g. separated) and phi_eq (phi
    where I_m is infinite). Returns (mu_p, I, I_v, phi_eq)."""
    mu1, mu2, b, eta0, rho_s, d = P[4], P[5], P[6], P[8], P[18], P[19]
    if p > 0.0:
        Iv = eta0 * g / p
        I = g * d * np.sqrt(rho_s / p)
        mu = laws.friction(Iv, Im, phi, a, mu1, mu2, b)
    else:
        Iv, I, mu = np.inf, np.inf, np.inf
    phieq = phim / (1.0 + a * Im) if np.isfinite(Im) else phi
    return mu, I, Iv, phieq


@_jit
def _correct(p_tr, tau_tr, phi, f, dt, P, g_prev, newton, beta_start, g_start):
    """The plastic correction of one point from its trial invariants p*, tau* [Pa] (module
    docstring, step 2): returns (case, gdot_p, p, I_m, beta, xi1, xi2, evaluations).

    ``g_prev``: warm start of a jammed point's dilatant solve (see :func:`update_point`);
    ``beta_start``, ``g_start``: an iterate of :func:`_newton_2d`'s pair from the caller
    (update_block's Newton), from which _newton_2d continues when it lies in the bracket
    (g_start > 0); otherwise (e.g. -1, -1) it starts from its own estimates. Either only moves
    where the solve starts, not its tolerance.
    """
    phi_c, phi_j, a0, ainf = P[0], P[1], P[2], P[3]
    mu1, mu2, b, eta0 = P[4], P[5], P[6], P[8]
    G, K, rho_s, d, K3 = P[16], P[17], P[18], P[19], P[20]
    phim = laws.phi_m(f, phi_c, phi_j)
    a = laws.dilatancy_a(f, a0, ainf)
    Gdt, Kdt, rd2 = G * dt, K * dt, rho_s * d * d
    case, iters = ELASTIC, 0
    g, xi1, xi2 = 0.0, 0.0, 0.0
    beta_guess, beta_c, gc = 0.0, 0.0, 0.0
    p, Im, beta = p_tr, 0.0, 0.0
    y = phim - phi
    # the largest pressure dilatancy can give: beta -> K3 phi at gdot_p = tau*/(G dt)
    p_dil = Kdt * tau_tr / Gdt * K3 * phi
    if p_tr + p_dil <= 0.0:                                   # separation: stress free
        return SEPARATED, tau_tr / Gdt, 0.0, np.inf, 0.0, -p_tr / Kdt, 0.0, 0
    if P[21] == 1.0 and y > 0.0 and p_tr >= 0.0 and tau_tr <= (mu1 - K3 * y) * p_tr:
        return ELASTIC, 0.0, p_tr, 0.0, -K3 * y, 0.0, 0.0, 0   # mpm_3d: admissible below jamming
    if y > 0.0:                                               # try shear flow + compaction
        gc, pc = _critical_state(tau_tr, phi, y, a, Gdt, mu1, mu2, b, eta0, rho_s, d)
        if pc <= p_tr:
            return COMPACTION, gc, pc, y / (a * phi), 0.0, 0.0, (pc - p_tr) / Kdt, 0
        # dilatant: K dt beta gdot ~ p - p*, with gdot ~ gc, p ~ pc
        beta_guess = (pc - p_tr) / (Kdt * gc) if gc > 0.0 else 0.0
        # to first order in beta, p = pc (1 - 2 beta I_m'/I_m) (I_m = y/(a phi) at beta = 0)
        beta_c = (pc - p_tr) / (Kdt * gc + 2.0 * pc * phim / (phi * y * K3))
    beta_lo = max(0.0, K3 * (phi - phim))
    if y <= 0.0:
        # R(beta_lo) at phi_eq = phi_m: I_m = 0, so gdot = 0, p = p*, mu_p = mu_1
        r_lo = tau_tr - (mu1 + beta_lo) * p_tr
        if r_lo <= 0.0:                                       # jammed and below yield: elastic
            return ELASTIC, 0.0, p_tr, 0.0, beta_lo, 0.0, 0.0, 0
    else:
        r_lo = np.nan                                         # evaluated only if needed
    # start of the solve, (beta, gdot): below jamming, the compaction estimates (pc, gc)
    # corrected to first order in beta (this step's critical-state rate gc is a better start than
    # the previous step's rate); jammed (phi >= phi_m), the previous step's rate (warm start) if
    # there is one, else the rate that would return tau* to mu_1 p*, and beta from the I_m
    # relation at that rate
    beta_top = beta_lo + (K3 * phi - beta_lo) * (1.0 - 1e-15)
    bs = beta_lo
    if newton:
        warm = g_prev > 0.0 and g_prev < np.inf
        if beta_lo < beta_start < beta_top and 0.0 < g_start < np.inf:
            g0, b0 = g_start, beta_start
        elif y > 0.0:
            g0 = gc
            b0 = beta_c
        else:
            g0 = g_prev if warm else max(tau_tr - mu1 * p_tr, 0.0) / Gdt
            # I_m from p I_m^2 = rd2 g^2 + 2 eta0 g at p ~ p* + K dt beta g, twice
            Ag = rd2 * g0 * g0 + 2.0 * eta0 * g0
            b0 = beta_lo
            for _ in range(2):
                b0 = K3 * (phi - phim / (1.0 + a * np.sqrt(Ag / (p_tr + Kdt * b0 * g0))))
        if not beta_lo < b0 < beta_top:
            b0 = beta_lo + 1e-3 * (beta_top - beta_lo)
        if g0 > 0.0 and p_tr > 0.0:
            # no settled start (far from the solution): straight to the bracket
            bs = _newton_2d(b0, g0, beta_lo, beta_top, phi, phim, a, p_tr, tau_tr, Gdt, Kdt, eta0,
                            rd2, K3, mu1, mu2, b)
    beta, g, p, Im, iters = _dilatant_flow(beta_lo, r_lo, beta_guess, bs, phi, phim, a, p_tr,
                                           tau_tr, Gdt, Kdt, eta0, rd2, K3, mu1, mu2, b, newton,
                                           g_prev if 0.0 < g_prev < np.inf else -1.0)
    return FAILED if iters < 0 else SHEAR_FLOW, g, p, Im, beta, xi1, xi2, iters


@_jit
def update_point(sig, L, phi, f, dt, P, sig_out, out, g_prev=-1.0, newton=True):
    """Advance one material point by dt [s] (see module docstring); writes sig_out and out[:NOUT].

    ``g_prev``: the point's plastic shear rate of the previous step [1/s] (out[1] of that step),
    the warm start of the dilatant solve of a jammed point (phi >= phi_m) that yields; below
    jamming this step's critical-state rate is the better start and ``g_prev`` is not used. A
    negative or non-finite value means none. It only changes where the solve starts, not its
    tolerance: results agree with the cold start to the solver's convergence test.
    ``newton=False`` solves by the bracket alone (the reference).
    """
    phi_c, phi_j, a0, ainf = P[0], P[1], P[2], P[3]
    v1, al1, v2, al2 = P[9], P[10], P[11], P[12]
    G, K = P[16], P[17]
    elastic_trial(sig, L, dt, G, K, sig_out)
    p_tr = -(sig_out[0, 0] + sig_out[1, 1] + sig_out[2, 2]) / 3.0
    ss = 0.0
    for i in range(3):
        for j in range(3):
            sij = sig_out[i, j] + (p_tr if i == j else 0.0)
            ss += sij * sij
    tau_tr = np.sqrt(0.5 * ss)
    case, g, p, Im, beta, xi1, xi2, iters = _correct(p_tr, tau_tr, phi, f, dt, P, g_prev, newton,
                                                     -1.0, -1.0)
    taubar, scale, f1 = _structure_tail(f, phi, g, tau_tr, G * dt, P, dt,
                                        laws.inv_eta_B(phi, phi_j, v1, al1, v2, al2),
                                        case == SEPARATED)
    mu, I, Iv, phieq = _flow_outputs(phi, laws.phi_m(f, phi_c, phi_j),
                                     laws.dilatancy_a(f, a0, ainf), g, p, Im, P)
    for i in range(3):
        for j in range(3):
            dev = sig_out[i, j] + (p_tr if i == j else 0.0)
            sig_out[i, j] = scale * dev - (p if i == j else 0.0)
    out[0], out[1], out[2], out[3], out[4] = f1, g, xi1, xi2, mu
    out[5], out[6], out[7], out[8], out[9] = I, Iv, Im, beta, phieq
    out[10], out[11], out[12], out[13] = taubar, p, case, iters


#: points per block of :func:`update_block` (its work arrays: (NWORK, BLOCK), the stress
#: (NSTRESS, BLOCK))
BLOCK = 256
#: rows of update_block's structure-of-arrays stress: sigma_xx, yy, zz, xy, xz, yz
NSTRESS = 6
#: rows of update_block's work array W: _NW of the block's points, the same _NW rows for the
#: points of the retry (packed, :func:`block_retry`), their phi, f and column in the block
_PTR, _TAU, _BETA, _G, _CASE, _GF, _PF, _IM, _INVB, _ITER = range(10)
_NW = 10
_RPHI, _RF, _RIDX = 2 * _NW, 2 * _NW + 1, 2 * _NW + 2
NWORK = 2 * _NW + 3
#: Newton steps on (beta, gdot_p) that :func:`update_block` takes in step for a whole block,
#: from _correct's start below jamming (after three, update_point's convergence test passes at
#: 84-89% of the flowing points of the mpm2d benchmark's shears, the others going through
#: block_retry; a fourth for all would leave some converged points short of the test)
_LANE_NEWTON = 3
#: Newton steps of :func:`block_retry` on the points the first test leaves unconverged with
#: their iterate in the bracket (11-16% of the flowing points), packed: after them the test
#: passes at all of them in the benchmark's shears (before, _correct solved them)
_RETRY_NEWTON = 2
#: update_block's case code of a point it hands to :func:`_correct` (with its Newton iterate as
#: the start of the dilatant solve: _HANDED_START; without: _HANDED); _RETRY: unconverged, its
#: iterate in the bracket (for block_retry, which leaves it _HANDED_START or finished)
_HANDED, _HANDED_START, _RETRY = -3.0, -2.0, -4.0
_SEPARATED, _ELASTIC, _COMPACTION = float(SEPARATED), float(ELASTIC), float(COMPACTION)

# The stages' loops are SIMD code only while they store few rows of W (each store is one more
# pointer whose overlap with the others the compiler checks at run time; past a handful it
# leaves the loop scalar): phi_m, a and the bracket are recomputed from f and phi where needed.
_stage = nb.njit(cache=True, error_model="numpy", inline="always")


@_stage
def block_start(S, phi, f, dt, P, W):
    """update_block stage 1: the trial invariants, the critical-state estimates, the case of
    every point whose case has a closed form (separated, elastic, shear flow + compaction) with
    its gdot_p and p, and the start of the others' Newton (branch-free: SIMD)."""
    mu1, mu2, b, eta0 = P[4], P[5], P[6], P[8]
    G, K, rho_s, d, K3 = P[16], P[17], P[18], P[19], P[20]
    phi_c, phi_j, a0, ainf = P[0], P[1], P[2], P[3]
    Gdt, Kdt = G * dt, K * dt
    mpm_3d = P[21] == 1.0
    for k in range(phi.shape[0]):
        s0, s1, s2, s3, s4, s5 = S[0, k], S[1, k], S[2, k], S[3, k], S[4, k], S[5, k]
        p_tr = -(s0 + s1 + s2) / 3.0
        d0, d1, d2 = s0 + p_tr, s1 + p_tr, s2 + p_tr
        tau_tr = np.sqrt(0.5 * (d0 * d0 + d1 * d1 + d2 * d2) + (s3 * s3 + s4 * s4 + s5 * s5))
        ph = phi[k]
        phim = laws.phi_m(f[k], phi_c, phi_j)
        a = laws.dilatancy_a(f[k], a0, ainf)
        y = phim - ph
        gc, pc = _critical_state(tau_tr, ph, y, a, Gdt, mu1, mu2, b, eta0, rho_s, d)
        beta_lo = max(0.0, K3 * (ph - phim))
        beta_top = beta_lo + (K3 * ph - beta_lo) * (1.0 - 1e-15)
        # the start of the dilatant solve below jamming: _correct's, the compaction estimates
        # (gc, pc) corrected to first order in beta
        b0 = (pc - p_tr) / (Kdt * gc + 2.0 * pc * phim / (ph * y * K3))
        # update_point's cases in its order (_correct), as exclusive masks, and the values of
        # the closed-form ones (every operand computed first, then selects)
        sep = p_tr + Kdt * tau_tr / Gdt * K3 * ph <= 0.0
        el3 = (y > 0.0) & (p_tr >= 0.0) & (tau_tr <= (mu1 - K3 * y) * p_tr) & mpm_3d
        el = (el3 | ((y <= 0.0) & (tau_tr - (mu1 + beta_lo) * p_tr <= 0.0))) & (not sep)
        comp = (y > 0.0) & (pc <= p_tr) & (not sep) & (not el)
        dil = (y > 0.0) & (p_tr > 0.0) & (gc > 0.0) & (beta_lo < b0) & (b0 < beta_top)
        g_sep = tau_tr / Gdt
        cs = _HANDED_START if dil else _HANDED
        cs = _COMPACTION if comp else cs
        cs = _ELASTIC if el else cs
        cs = _SEPARATED if sep else cs
        gf = gc if comp else 0.0
        pf = pc if comp else 0.0
        W[_PTR, k], W[_TAU, k], W[_BETA, k], W[_G, k], W[_CASE, k] = p_tr, tau_tr, b0, gc, cs
        W[_GF, k] = g_sep if sep else gf
        W[_PF, k] = p_tr if el else pf


@_stage
def block_newton(phi, f, dt, P, W, steps=_LANE_NEWTON):
    """update_block stage 2: ``steps`` steps of the 2-D Newton of :func:`_newton_2d` (its
    equations F1, F2) at every point in step (branch-free: SIMD)."""
    phi_c, phi_j, a0, ainf, mu1, mu2, b, eta0 = P[0], P[1], P[2], P[3], P[4], P[5], P[6], P[8]
    Gdt, Kdt, rd2, iK3 = P[16] * dt, P[17] * dt, P[18] * P[19] * P[19], 1.0 / P[20]
    for _ in range(steps):
        for k in range(phi.shape[0]):
            beta, gk = W[_BETA, k], W[_G, k]
            db, dg = _newton_2d_step(beta, gk, phi[k], laws.phi_m(f[k], phi_c, phi_j),
                                     laws.dilatancy_a(f[k], a0, ainf), W[_PTR, k], W[_TAU, k],
                                     Gdt, Kdt, eta0, rd2, iK3, mu1, mu2, b)
            W[_BETA, k], W[_G, k] = beta + db, gk + dg


@_stage
def block_test(phi, f, dt, P, W, evals=1.0):
    """update_block stage 3: R(beta) of :func:`_dilatant_flow` at the Newton iterate (gdot(beta)
    in closed form), its slope (:func:`_slope`) and update_point's convergence test (the exits
    of _dilatant_flow's Newton: |R| at the roundoff floor, or a step below 1e-14 beta with
    |R| <= 1e-12 of the stress); a point that passes is finished, one that does not with its
    iterate in the bracket is marked for :func:`block_retry` (branch-free: SIMD; three
    divisions and a square root). ``evals``: the block's residual evaluations at a dilatant
    point so far (W row _ITER; 0 at the others)."""
    phi_c, phi_j, a0, ainf, mu1, mu2, b, eta0 = P[0], P[1], P[2], P[3], P[4], P[5], P[6], P[8]
    K3 = P[20]
    Gdt, Kdt, rd2, iK3 = P[16] * dt, P[17] * dt, P[18] * P[19] * P[19], 1.0 / K3
    for k in range(phi.shape[0]):
        beta, p_tr, tau_tr, ph = W[_BETA, k], W[_PTR, k], W[_TAU, k], phi[k]
        cs, gf, pf = W[_CASE, k], W[_GF, k], W[_PF, k]
        phim = laws.phi_m(f[k], phi_c, phi_j)
        a = laws.dilatancy_a(f[k], a0, ainf)
        beta_lo = max(0.0, K3 * (ph - phim))
        beta_top = beta_lo + (K3 * ph - beta_lo) * (1.0 - 1e-15)
        # R = tau* - G dt g - (mu_p + beta) p with laws.friction's terms multiplied through by
        # p: (mu_1 + beta) p + (mu_2 - mu_1) U p + V g, U = I_m/(I_m + b), V = 5/2 phi eta0/(a I_m)
        # (F2 of _newton_2d at g = gdot(beta)); 1/(a x), U and V from one reciprocal
        x, w, ax, wb, q, iax, Im, V = _im_terms(beta, ph, phim, a, b, eta0, iK3)
        Im2 = Im * Im
        U = w * w * ax * q
        c = 2.5 * ph * eta0
        bq = 2.0 * eta0 - Kdt * beta * Im2
        cq = p_tr * Im2
        sq = np.sqrt(bq * bq + 4.0 * rd2 * cq)
        gk = 2.0 * cq / (bq + sq) if bq > 0.0 else (-bq + sq) / (2.0 * rd2)
        p = p_tr + Kdt * beta * gk
        R = tau_tr - Gdt * gk - (mu1 + beta) * p - (mu2 - mu1) * U * p - V * gk
        # its slope (_slope's chain rule in these variables; w + x = phi_m)
        dIm = phim * a * iax * iax * iK3
        dg = (Kdt * Im2 * gk + 2.0 * p * Im * dIm) / sq
        dp = Kdt * (gk + beta * dg)
        dU = b * a * phim * iK3 * (ax * w * q) ** 2
        dV = -c * phim * iK3 * (ax * wb * q) ** 2
        dR = (-Gdt * dg - p - (mu1 + beta) * dp - (mu2 - mu1) * (dU * p + U * dp) - dV * gk
              - V * dg)
        floor = 2e-15 * (tau_tr + mu1 * abs(p_tr))
        conv = (abs(R) <= floor) | ((abs(R) <= 1e-14 * abs(beta) * abs(dR))
                                    & (abs(R) <= 1e-12 * (tau_tr - Gdt * gk + mu1 * p) + floor))
        dil = cs == _HANDED_START
        inb = (beta_lo < beta) & (beta < beta_top) & (gk > 0.0) & (gk < np.inf) & dil
        ok = conv & inb
        W[_CASE, k] = SHEAR_FLOW if ok else (_RETRY if inb else cs)
        W[_GF, k] = gk if ok else gf
        W[_PF, k] = p if ok else pf
        W[_IM, k] = Im
        W[_ITER, k] = evals if dil else 0.0


@_stage
def block_retry(phi, f, dt, P, W):
    """update_block stage 3b: the points block_test marks (_RETRY) packed into W's second set
    of rows, _RETRY_NEWTON more Newton steps and the test there (SIMD on the packed points),
    then back: a point still unconverged goes to _correct from its iterate (_HANDED_START)."""
    m = 0
    for k in range(phi.shape[0]):
        if W[_CASE, k] == _RETRY:
            W[_RIDX, m] = k
            m += 1
    if m == 0:
        return
    R = W[_NW:2 * _NW]
    for j in range(m):
        k = int(W[_RIDX, j])
        R[_BETA, j], R[_G, j] = W[_BETA, k], W[_G, k]
        R[_PTR, j], R[_TAU, j] = W[_PTR, k], W[_TAU, k]
        R[_GF, j], R[_PF, j], W[_RPHI, j], W[_RF, j] = W[_GF, k], W[_PF, k], phi[k], f[k]
        R[_CASE, j] = _HANDED_START
    ph, fr = W[_RPHI, :m], W[_RF, :m]
    block_newton(ph, fr, dt, P, R, _RETRY_NEWTON)
    block_test(ph, fr, dt, P, R, 2.0)
    for j in range(m):
        k = int(W[_RIDX, j])
        cs = R[_CASE, j]
        W[_CASE, k] = _HANDED_START if cs == _RETRY else cs
        W[_BETA, k], W[_G, k], W[_GF, k], W[_PF, k] = R[_BETA, j], R[_G, j], R[_GF, j], R[_PF, j]
        W[_IM, k], W[_ITER, k] = R[_IM, j], R[_ITER, j]


@_stage
def block_inv_eta_B(phi, P, W):
    """update_block stage 4: 1/eta_B of every point (Eq. 9; rheology.vecmath: SIMD)."""
    phi_j, v1, al1, v2, al2 = P[1], P[9], P[10], P[11], P[12]
    for k in range(phi.shape[0]):
        W[_INVB, k] = laws.inv_eta_B(phi[k], phi_j, v1, al1, v2, al2)


@_stage
def block_handed(phi, f, g, dt, P, W):
    """update_block stage 5: the points without a closed form or an accepted solve through
    :func:`_correct` (update_point's solve; a dilatant point below jamming from the block's
    iterate). They end in shear flow (or FAILED): xi1 = xi2 = 0."""
    for k in range(phi.shape[0]):
        cs = W[_CASE, k]
        if cs < -1.0:
            start = cs == _HANDED_START
            c, gk, p, Im, beta, _, _, it = _correct(W[_PTR, k], W[_TAU, k], phi[k], f[k], dt, P,
                                                    g[k], True, W[_BETA, k] if start else -1.0,
                                                    W[_G, k] if start else -1.0)
            W[_CASE, k], W[_GF, k], W[_PF, k], W[_IM, k], W[_BETA, k] = c, gk, p, Im, beta
            # evaluations: the block's own (at its iterates) and _correct's
            W[_ITER, k] = it if (it < 0 or not start) else it + W[_ITER, k]


@_stage
def block_finish(S, phi, f, g, case, dt, P, W):
    """update_block stage 6: taubar, the structure step and the new stress of every point
    (branch-free: SIMD); f, g and case written."""
    Gdt = P[16] * dt
    # the parameters as a tuple: values, whose loads are not redone after every store (array
    # loads would be, and keep the loop scalar)
    Pt = (P[0], P[1], P[2], P[3], P[4], P[5], P[6], P[7], P[8], P[9], P[10], P[11], P[12],
          P[13], P[14], P[15], P[16], P[17], P[18], P[19], P[20])
    for k in range(phi.shape[0]):
        cs, gk, p, p_tr, tau_tr = W[_CASE, k], W[_GF, k], W[_PF, k], W[_PTR, k], W[_TAU, k]
        ph, fk, invB = phi[k], f[k], W[_INVB, k]
        s0, s1, s2, s3, s4, s5 = S[0, k], S[1, k], S[2, k], S[3, k], S[4, k], S[5, k]
        taubar, scale, f1 = _structure_tail(fk, ph, gk, tau_tr, Gdt, Pt, dt, invB,
                                            cs == SEPARATED)
        S[0, k] = scale * (s0 + p_tr) - p
        S[1, k] = scale * (s1 + p_tr) - p
        S[2, k] = scale * (s2 + p_tr) - p
        S[3, k], S[4, k], S[5, k] = scale * s3, scale * s4, scale * s5
        f[k], g[k], case[k] = f1, gk, cs


@_jit
def update_block(S, phi, f, g, case, dt, P, W, out):
    """:func:`update_point` on a block of n = len(phi) <= BLOCK points, in vectorised stages.

    Parameters
    ----------
    S : (NSTRESS, >= n) float array
        Structure-of-arrays stress (rows xx, yy, zz, xy, xz, yz; symmetric) [Pa]: on entry the
        elastic trial sigma* (:func:`jaumann_elastic` of the point's sigma_n and L), on return
        sigma_{n+1}.
    phi : (n,) volume fraction.
    f : (n,) structure, advanced in place.
    g : (n,) on entry each point's previous plastic shear rate (the warm start of a jammed
        point's solve, :func:`update_point`; negative: none), on return the new gdot_p [1/s].
    case : (n,) written: the case code (float).
    dt, P : step [s] and parameter vector (:func:`kernel_parameters`).
    W : (NWORK, >= n) work array.
    out : (n, NOUT) or (0, NOUT)
        Diagnostic outputs as :func:`update_point` writes them, or nothing (0 rows: a caller
        that keeps only the stress, f, gdot_p and the case, e.g. mpm2d).

    The scalar update is a chain of dependent divisions and square roots per point, so it runs
    at the latency of that chain; here the same arithmetic goes through the block one stage at
    a time (:func:`block_start`, :func:`block_newton`, :func:`block_test`,
    :func:`block_retry`, :func:`block_inv_eta_B`, :func:`block_handed`, :func:`block_finish`),
    each but block_handed a branch-free loop over the points (block_retry's over the points it
    packs) that the compiler turns into SIMD instructions. A point the vector stages do not
    finish goes through :func:`_correct`, so the results are those of update_point to its
    convergence test.
    """
    block_start(S, phi, f, dt, P, W)
    block_newton(phi, f, dt, P, W)
    block_test(phi, f, dt, P, W)
    block_retry(phi, f, dt, P, W)
    block_inv_eta_B(phi, P, W)
    block_handed(phi, f, g, dt, P, W)
    if out.shape[0] > 0:
        _block_outputs(phi, f, dt, P, W, out)
    block_finish(S, phi, f, g, case, dt, P, W)


@_jit
def _block_outputs(phi, f, dt, P, W, out):
    """update_block's diagnostic outputs (the columns of :data:`OUT_FIELDS`) from its work
    array, before its last stage (f is still f_n there)."""
    Gdt, Kdt, K3 = P[16] * dt, P[17] * dt, P[20]
    for k in range(phi.shape[0]):
        cs, gk, p, p_tr, tau_tr = W[_CASE, k], W[_GF, k], W[_PF, k], W[_PTR, k], W[_TAU, k]
        ph = phi[k]
        phim, a = laws.phi_m(f[k], P[0], P[1]), laws.dilatancy_a(f[k], P[2], P[3])
        sep = cs == SEPARATED
        Im, beta, xi1, xi2 = W[_IM, k], W[_BETA, k], 0.0, 0.0
        if cs == COMPACTION:
            Im, beta, xi2 = (phim - ph) / (a * ph), 0.0, (p - p_tr) / Kdt
        elif cs == ELASTIC:
            Im, beta = 0.0, -K3 * (phim - ph)
        elif sep:
            Im, beta, xi1 = np.inf, 0.0, -p_tr / Kdt
        taubar, _, f1 = _structure_tail(f[k], ph, gk, tau_tr, Gdt, P, dt, W[_INVB, k], sep)
        mu, I, Iv, phieq = _flow_outputs(ph, phim, a, gk, p, Im, P)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4] = f1, gk, xi1, xi2, mu
        out[k, 5], out[k, 6], out[k, 7], out[k, 8], out[k, 9] = I, Iv, Im, beta, phieq
        out[k, 10], out[k, 11], out[k, 12], out[k, 13] = taubar, p, cs, W[_ITER, k]


@nb.njit(cache=True, error_model="numpy", inline="always")
def trial_to_block(sig, L, k, dt, G, K, S, j):
    """The Jaumann trial (:func:`jaumann_elastic`) of row k of the (N, 3, 3) stress and
    gradient into column j of update_block's stress S; returns sigma_n's pressure."""
    r = jaumann_elastic((sig[k, 0, 0], sig[k, 0, 1], sig[k, 0, 2], sig[k, 1, 0], sig[k, 1, 1],
                         sig[k, 1, 2], sig[k, 2, 0], sig[k, 2, 1], sig[k, 2, 2]),
                        (L[k, 0, 0], L[k, 0, 1], L[k, 0, 2], L[k, 1, 0], L[k, 1, 1],
                         L[k, 1, 2], L[k, 2, 0], L[k, 2, 1], L[k, 2, 2]), dt, G, K)
    S[0, j], S[1, j], S[2, j], S[3, j], S[4, j], S[5, j] = r[0], r[4], r[8], r[1], r[2], r[5]


def _update_loop(sig, L, phi, f, dt, P, sig_out, out, g_prev=None, newton=True):
    """Loop of the update over N points (arrays (N,3,3), (N,), out (N, NOUT)): blocks of
    :func:`update_block`, or with ``newton=False`` :func:`update_point` by the bracket alone.

    ``g_prev`` (N,), optional: each point's plastic shear rate of the previous step, the warm
    start (negative: none); it is not written (out[:, 1] holds the new rates). Chunks of four
    blocks run in parallel, each with its own work arrays.
    """
    N = phi.shape[0]
    G, K = P[16], P[17]
    for c in nb.prange((N + 4 * BLOCK - 1) // (4 * BLOCK)):
        S = np.empty((NSTRESS, BLOCK))
        W = np.empty((NWORK, BLOCK))
        fb, gb, cb = np.empty(BLOCK), np.empty(BLOCK), np.empty(BLOCK)
        for lo in range(4 * BLOCK * c, min(4 * BLOCK * (c + 1), N), BLOCK):
            hi = min(lo + BLOCK, N)
            if not newton:
                for k in range(lo, hi):
                    update_point(sig[k], L[k], phi[k], f[k], dt, P, sig_out[k], out[k], -1.0,
                                 False)
                continue
            for k in range(hi - lo):
                trial_to_block(sig, L, lo + k, dt, G, K, S, k)
                fb[k] = f[lo + k]
            if g_prev is None:
                gb[:] = -1.0
            else:
                gb[:hi - lo] = g_prev[lo:hi]
            n = hi - lo
            update_block(S, phi[lo:hi], fb[:n], gb[:n], cb[:n], dt, P, W, out[lo:hi])
            for k in range(hi - lo):
                so = sig_out[lo + k]
                so[0, 0], so[1, 1], so[2, 2] = S[0, k], S[1, k], S[2, k]
                so[0, 1] = so[1, 0] = S[3, k]
                so[0, 2] = so[2, 0] = S[4, k]
                so[1, 2] = so[2, 1] = S[5, k]


#: Parallel (prange) loop over points: the entry point for large batches (MPM, 1-D grids).
update_points = nb.njit(cache=True, parallel=True, error_model="numpy")(_update_loop)
#: The same loop compiled serially: no thread start-up per call, for a few points stepped often.
update_points_serial = nb.njit(cache=True, error_model="numpy")(_update_loop)


@dataclass(frozen=True)
class LocalUpdate:
    """Result of :func:`local_update` (arrays shaped like the input points).

    Attributes
    ----------
    stress : (..., 3, 3) granular effective stress at the end of the step [Pa]
    f : structure at the end of the step [-]
    shear_rate_p : plastic shear rate gdot_p [1/s]
    xi1, xi2 : separation (>= 0) and compaction (<= 0) plastic volume rates [1/s]
    mu_p, I, I_v, I_m, beta, phi_eq : friction, inertial numbers, dilation angle, critical packing
    taubar, pressure : equivalent shear stress and pressure at the end of the step [Pa]
    case : 0 elastic, 1 separated, 2 shear flow, 3 shear flow + compaction
    evaluations : residual evaluations of the dilatant solve (0 for the closed-form cases)
    """

    stress: np.ndarray
    f: np.ndarray
    shear_rate_p: np.ndarray
    xi1: np.ndarray
    xi2: np.ndarray
    mu_p: np.ndarray
    I: np.ndarray
    I_v: np.ndarray
    I_m: np.ndarray
    beta: np.ndarray
    phi_eq: np.ndarray
    taubar: np.ndarray
    pressure: np.ndarray
    case: np.ndarray
    evaluations: np.ndarray


def kernel_parameters(m: Material) -> np.ndarray:
    """Validated parameter vector for :func:`update_points` (needs G, K and K0 set)."""
    m.require("G", "K", "K0")
    return m.kernel_array()


def local_update(stress, velocity_gradient, phi, f, dt: float, m: Material | str,
                 plastic_rate=None) -> LocalUpdate:
    """Advance the Table 8 granular law by one implicit step at every material point.

    Parameters
    ----------
    stress : array_like, shape (..., 3, 3)
        Granular effective stress sigma_n [Pa] (tension positive), symmetric.
    velocity_gradient : array_like, shape (..., 3, 3)
        Granular velocity gradient L_ij = d v_i / d x_j over the step [1/s].
    phi : array_like, shape (...)
        Volume fraction, 0 <= phi < 1 (phi >= phi_m is the jammed solid).
    f : array_like, shape (...)
        Structure at the start of the step, 0 <= f <= 1.
    dt : float
        Time step [s] > 0. The update is implicit (unconditionally stable in the plastic
        correction and the structure); the explicit Jaumann spin limits dt |W| << 1.
    m : Material or str
        The parameter set or its name; needs G, K and K0.
    plastic_rate : numpy.ndarray of float, shape (...) like the points, optional
        Warm start, read and written: on entry each point's plastic shear rate of the previous
        step [1/s] (negative or NaN: none, e.g. ``np.full(shape, -1.0)`` before the first step),
        on return the new one (``shear_rate_p``). It moves the start of the dilatant solve of
        jammed points (phi >= phi_m) that yield; the tolerance is the same, results agree with a
        cold start to it.

    Returns
    -------
    LocalUpdate
        Arrays shaped like the points; with zero points, empty arrays of those shapes.

    Raises
    ------
    ValueError
        Bad shapes, non-finite or out-of-range inputs (``plastic_rate`` not a writable float
        array of the points' shape).
    RuntimeError
        If the solve fails at any point (with the point's state).
    """
    P = kernel_parameters(get_material(m))
    sig = np.asarray(stress, dtype=float)
    L = np.asarray(velocity_gradient, dtype=float)
    if sig.shape[-2:] != (3, 3) or L.shape[-2:] != (3, 3):
        raise ValueError(f"stress and velocity_gradient must have shape (..., 3, 3), got "
                         f"{sig.shape} and {L.shape}")
    check_range("stress", sig)
    check_range("velocity_gradient", L)
    if sig.size and not np.allclose(sig, np.swapaxes(sig, -1, -2), rtol=1e-12,
                                    atol=1e-12 * (1 + np.abs(sig).max())):
        raise ValueError("stress must be symmetric (sigma_ij = sigma_ji)")
    check_range("dt", dt, 0.0, None, lo_closed=False)
    shape = np.broadcast_shapes(sig.shape[:-2], L.shape[:-2], np.shape(phi), np.shape(f))
    phi = check_range("phi", np.broadcast_to(phi, shape), 0.0, 1.0, hi_closed=False)
    f = check_range("f", np.broadcast_to(f, shape), 0.0, 1.0)
    n = int(np.prod(shape))
    g_prev = None
    if plastic_rate is not None:
        if (not isinstance(plastic_rate, np.ndarray) or plastic_rate.dtype != np.float64
                or plastic_rate.shape != shape or not plastic_rate.flags.writeable):
            raise ValueError(f"plastic_rate must be a writable float64 array of the points' shape "
                             f"{shape}, got {type(plastic_rate).__name__} "
                             f"{getattr(plastic_rate, 'shape', '')}")
        if np.any(np.isposinf(plastic_rate)):
            raise ValueError("plastic_rate must be finite or negative/NaN (no warm start), got inf")
        g_prev = np.ascontiguousarray(plastic_rate.reshape(n))
    sig_in = np.ascontiguousarray(np.broadcast_to(sig, shape + (3, 3)).reshape(n, 3, 3))
    L_in = np.ascontiguousarray(np.broadcast_to(L, shape + (3, 3)).reshape(n, 3, 3))
    sig_out = np.empty_like(sig_in)
    out = np.empty((n, NOUT))
    if n:
        loop = update_points if n >= 256 else update_points_serial
        args = (sig_in, L_in, np.ascontiguousarray(phi.reshape(n)),
                np.ascontiguousarray(f.reshape(n)), float(dt), P, sig_out, out)
        loop(*args) if g_prev is None else loop(*args, g_prev)
    failed = np.flatnonzero(out[:, 12] == FAILED)
    if failed.size:
        k = failed[0]
        raise RuntimeError(f"local update failed at {failed.size} point(s); first: index {k}, "
                           f"phi = {phi.reshape(n)[k]:.6g}, f = {f.reshape(n)[k]:.6g}, "
                           f"stress = {sig_in[k].tolist()}, dt = {dt:g}")
    if plastic_rate is not None:
        plastic_rate[...] = out[:, 1].reshape(shape)
    col = {name: out[:, i].reshape(shape) for i, name in enumerate(OUT_FIELDS)}
    return LocalUpdate(stress=sig_out.reshape(shape + (3, 3)), f=col["f"],
                       shear_rate_p=col["shear_rate_p"], xi1=col["xi1"], xi2=col["xi2"],
                       mu_p=col["mu_p"], I=col["I"], I_v=col["I_v"], I_m=col["I_m"],
                       beta=col["beta"], phi_eq=col["phi_eq"], taubar=col["taubar"],
                       pressure=col["pressure"], case=col["case"].astype(int),
                       evaluations=col["iterations"].astype(int))
