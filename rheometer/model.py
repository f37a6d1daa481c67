"""The reduced 0-D model of a sheared sample: paper Eqs. (35)-(37) generalised to any protocol.

A homogeneous sample in simple shear at volume fraction ``phi`` carries the granular shear stress
``taubar`` and the structure ``f``. Its plastic shear rate is the critical-state rate of
:func:`rheology.laws.critical_shear_rate` (Eq. 35 consistent with Eq. 1 and Table 8, multiplied
through by (phi_m - phi)^2 so that it is continuous through jamming and 0 when phi >= phi_m(f)).
This is the K -> inf limit of the Table 8 tensor law, in which the granular pressure is slaved to
the critical state. The unknowns and equations (one residual each, as IDA solves them)::

    y = [taubar, gap, gdot_p, gdot, strain]
    0 = taubar' - G (gdot - gdot_p)                         Eq. (36) with the imposed rate
    0 = gap'    + (phi_j - phi_c) df/dt(f, |taubar|, |gdot_p|) Table 8 structure law
    0 = gdot_p  - sign(taubar) gdot_cs(|taubar|, gap)        algebraic (Eq. 35)
    0 = gdot    - gdot_imposed(t)                            rate control (rest: gdot = 0), or
    0 = taubar + eta0 (1 + 5/2 phi) gdot - tau_imposed(t)    mixture-stress control
    0 = strain' - gdot

The shear stress and the rates are SIGNED: the Table 8 flow rule is isotropic (the plastic rate is
coaxial with the deviatoric stress), so in simple shear the plastic rate has the sign of the shear
stress and the magnitude of the critical-state law at |taubar|, and the structure law sees the
magnitudes (|taubar| in H and taubar/eta_B, |gdot_p| in the shear-rate terms). Where the stress
reverses (oscillation, a stress step below the granular stress, reversal after a shear step) the
plastic rate reverses with it; for taubar >= 0 this is the law of Eqs. (35)-(37) unchanged. The odd
extension is smooth at taubar = 0 to first order (gdot_cs is linear there, slope 1/eta_g).

The imposed value is constant, ramped (linear or logarithmic) or sinusoidal: SINE imposes
``v0 sin(omega (t - t0))`` (mixture-stress oscillation, amplitude v0 [Pa]), COSINE imposes
``v0 cos(omega (t - t0))`` (strain oscillation gamma0 sin(omega (t - t0)) as the rate
v0 = gamma0 omega), with omega = v1 [rad/s].

The structure is carried by the jamming gap ``gap = phi_m(f) - phi = (phi_j - phi_c)(f_jam - f)``
(negative when jammed), not by f: the plastic rate goes as gap^2 near jamming, and IDA's relative
error control then keeps the gap, and every rate, accurate to rtol however close the sample gets
to jamming (with f as the state the gap would only be resolved to ~rtol f (phi_j - phi_c) and a
solution approaching jamming asymptotically could step through it). f = f_jam - gap/(phi_j -
phi_c) is recovered exactly where it is needed.

``gdot_p`` and ``gdot`` are algebraic (declared to IDA). The eliminated form ("ode") keeps only
``[taubar, gap, strain]`` with ``gdot_p`` and ``gdot`` substituted; it is what ``scipy``'s ODE
solvers integrate in the benchmarks.

Numerics only live here: the physics is called from :mod:`rheology.laws` (numba-compiled
``register_jitable`` functions). Jacobian entries are exact derivatives of those same laws by the
complex step ``d g/d x = Im g(x + i h)/h`` (no subtractive cancellation, so exact to rounding
with ``h = 1e-30``): no formula is re-derived here.

Events (IDA root functions): the gap (jamming when it falls through 0, unjamming when it rises)
and ``strain - strain_target`` (a program step "until strain ...").
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rheology import laws
from rheology.materials import Material
from rheology.numba_cache import guard

guard(__file__)                          # drop cached kernels if rheology's laws changed
_jit = nb.njit(cache=True, error_model="numpy")

#: Indices of the DAE unknowns.
TAU, GAP, GP, GD, STRAIN = 0, 1, 2, 3, 4
NVAR = 5
#: Control modes and ramp kinds of a segment (entries 0 and 1 of the control vector).
RATE, STRESS = 0, 1
CONST, LINEAR, LOG, SINE, COSINE = 0, 1, 2, 3, 4
#: Number of root functions (jamming gap, strain target).
NEVENTS = 2
_H = 1e-30          # complex-step size (any tiny value: no cancellation)

# parameter vector layout (see parameters())
_PHI, _PHIC, _PHIJ, _A0, _AINF, _MU1, _MU2, _B, _ETA0, _D, _RHOS, _TSTAR, _INVB, _FM, _K0, \
    _XIEPS, _G, _ETAF = range(18)
#: where :func:`parameters` holds the fluid viscosity eta0 (1 + 5/2 phi) [Pa s]
ETA_FLUID = _ETAF


def parameters(m: Material, phi: float, G: float, K0: float) -> np.ndarray:
    """Parameter vector of the reduced model for material ``m`` at volume fraction ``phi``.

    ``G`` [Pa] and ``K0`` [-] are passed explicitly (the steady fits of the paper have none).
    """
    return np.array([phi, m.phi_c, m.phi_j, m.a0, m.a_inf, m.mu_c, m.mu2, m.b, m.eta0, m.d,
                     m.rho_s or 0.0, m.tau_star,
                     laws.inv_eta_B(phi, m.phi_j, m.varphi1, m.alpha1, m.varphi2, m.alpha2),
                     laws.f_max(phi, m.phi_c, m.phi_j, m.Delta), K0, m.xi_eps, G,
                     m.eta0 * (1.0 + 2.5 * phi)], dtype=float)


def control(mode: int, kind: int, v0: float, v1: float, t0: float, duration: float,
            strain_target: float = np.inf) -> np.ndarray:
    """Control vector of one segment: imposed rate [1/s] or mixture stress [Pa] from v0 to v1.

    ``kind`` is CONST (v0 throughout), LINEAR or LOG (geometric) over ``duration`` [s] from
    ``t0`` [s], or SINE / COSINE: ``v0 sin(v1 (t - t0))`` / ``v0 cos(v1 (t - t0))`` (amplitude
    v0, angular frequency v1 [rad/s]; ``duration`` is then informative); ``strain_target`` [-] is
    the absolute strain at which the segment stops.
    """
    return np.array([mode, kind, v0, v1, t0, duration, strain_target], dtype=float)


# ------------------------------------------------------------------ the laws, as used here
@_jit
def structure_of_gap(gap, P):
    """f = f_jam - gap/(phi_j - phi_c) [-] (real or complex)."""
    return (P[_PHIJ] - P[_PHI] - gap) / (P[_PHIJ] - P[_PHIC])


@_jit
def gap_of_structure(f, P):
    """Jamming gap phi_m(f) - phi [-] (real or complex)."""
    return laws.phi_m(f, P[_PHIC], P[_PHIJ]) - P[_PHI]


@_jit
def sign(x):
    """+1 for x >= 0, else -1 (of the real part: a constant for the complex step)."""
    return 1.0 if x.real >= 0.0 else -1.0


@_jit
def plastic_rate(taubar, gap, P):
    """Critical-state plastic shear rate gdot_cs(taubar, gap) [1/s] for taubar >= 0 (0 for
    taubar <= 0: the magnitude law; real or complex)."""
    a = laws.dilatancy_a(structure_of_gap(gap, P), P[_A0], P[_AINF])
    return laws.critical_shear_rate(taubar, P[_PHI], np.maximum(gap, 0.0), a, P[_MU1], P[_MU2],
                                    P[_B], P[_ETA0], P[_D], P[_RHOS])


@_jit
def signed_plastic_rate(taubar, gap, P):
    """sign(taubar) gdot_cs(|taubar|, gap) [1/s]: the plastic rate of a signed shear stress."""
    s = sign(taubar)
    return s * plastic_rate(s * taubar, gap, P)


@_jit
def gap_rate(gap, taubar, gp, P):
    """d gap/dt = -(phi_j - phi_c) df/dt of Table 8 [1/s] at this phi (real or complex), for
    the magnitudes taubar >= 0, gp >= 0."""
    f = structure_of_gap(gap, P)
    return -(P[_PHIJ] - P[_PHIC]) * laws.structure_rate(f, taubar, gp, P[_FM], P[_TSTAR], P[_INVB],
                                                        P[_K0], P[_XIEPS])


@_jit
def signed_gap_rate(gap, taubar, gp, P):
    """:func:`gap_rate` of signed taubar and gdot_p (the structure law sees their magnitudes)."""
    return gap_rate(gap, sign(taubar) * taubar, sign(gp) * gp, P)


@_jit
def _plastic_rate_d(taubar, gap, P):
    """(gdot_cs, d gdot_cs/d taubar, d gdot_cs/d gap) by complex step (magnitude law)."""
    g = plastic_rate(taubar, gap, P)
    gt = plastic_rate(taubar + 1j * _H, gap + 0j, P).imag / _H
    gy = plastic_rate(taubar + 0j, gap + 1j * _H, P).imag / _H
    return g, gt, gy


@_jit
def _gap_rate_d(gap, taubar, gp, P):
    """(d gap/dt, its partials d/d gap, d/d taubar, d/d gdot_p) by complex step (magnitudes)."""
    r = gap_rate(gap, taubar, gp, P)
    ry = gap_rate(gap + 1j * _H, taubar + 0j, gp + 0j, P).imag / _H
    rt = gap_rate(gap + 0j, taubar + 1j * _H, gp + 0j, P).imag / _H
    rg = gap_rate(gap + 0j, taubar + 0j, gp + 1j * _H, P).imag / _H
    return r, ry, rt, rg


@_jit
def _signed_plastic_rate_d(taubar, gap, P):
    """(gdot_p, d gdot_p/d taubar, d gdot_p/d gap) of :func:`signed_plastic_rate`."""
    s = sign(taubar)
    g, gt, gy = _plastic_rate_d(s * taubar, gap, P)
    return s * g, gt, s * gy


@_jit
def _signed_gap_rate_d(gap, taubar, gp, P):
    """(d gap/dt, d/d gap, d/d taubar, d/d gdot_p) of :func:`signed_gap_rate`."""
    st, sg = sign(taubar), sign(gp)
    r, ry, rt, rg = _gap_rate_d(gap, st * taubar, sg * gp, P)
    return r, ry, st * rt, sg * rg


@_jit
def imposed(t, C):
    """(value, d value/dt) of the imposed rate or stress at time t [s]."""
    kind, v0, v1, t0, T = C[1], C[2], C[3], C[4], C[5]
    if kind == SINE:
        ph = v1 * (t - t0)
        return v0 * np.sin(ph), v0 * v1 * np.cos(ph)
    if kind == COSINE:
        ph = v1 * (t - t0)
        return v0 * np.cos(ph), -v0 * v1 * np.sin(ph)
    if kind == CONST or T <= 0.0:
        return v0, 0.0
    s = min(max((t - t0) / T, 0.0), 1.0)
    inside = 1.0 if (t - t0) < T else 0.0
    if kind == LINEAR:
        return v0 + (v1 - v0) * s, inside * (v1 - v0) / T
    v = v0 * (v1 / v0) ** s
    return v, inside * v * np.log(v1 / v0) / T


@_jit
def shear_rate(t, taubar, P, C):
    """(gdot, d gdot/d taubar, d gdot/dt at fixed taubar) from the control."""
    v, dv = imposed(t, C)
    if C[0] == RATE:
        return v, 0.0, dv
    return (v - taubar) / P[_ETAF], -1.0 / P[_ETAF], dv / P[_ETAF]


# ------------------------------------------------------------------ DAE form
@_jit
def consistent_state(t, taubar, gap, strain, P, C, y, yp):
    """Fill (y, yp) consistent with the DAE at time t from (taubar, gap, strain)."""
    g, gt_, gtime = shear_rate(t, taubar, P, C)
    gp, gpt, gpy = _signed_plastic_rate_d(taubar, gap, P)
    taup = P[_G] * (g - gp)
    yp_gap = signed_gap_rate(gap, taubar, gp, P)
    y[TAU], y[GAP], y[GP], y[GD], y[STRAIN] = taubar, gap, gp, g, strain
    yp[TAU], yp[GAP], yp[STRAIN] = taup, yp_gap, g
    yp[GP] = gpt * taup + gpy * yp_gap
    yp[GD] = gtime + gt_ * taup


@_jit
def residual(t, y, yp, res, P, C):
    """DAE residuals (see module docstring)."""
    v, _ = imposed(t, C)
    res[TAU] = yp[TAU] - P[_G] * (y[GD] - y[GP])
    res[GAP] = yp[GAP] - signed_gap_rate(y[GAP], y[TAU], y[GP], P)
    res[GP] = y[GP] - signed_plastic_rate(y[TAU], y[GAP], P)
    if C[0] == RATE:
        res[GD] = y[GD] - v
    else:
        res[GD] = (y[TAU] + P[_ETAF] * y[GD] - v) / P[_ETAF]
    res[STRAIN] = yp[STRAIN] - y[GD]


@_jit
def jacobian(t, y, yp, cj, JJ, P, C):
    """JJ = d res/d y + cj d res/d yp of :func:`residual`, exact (complex-step partials)."""
    _, gt, gy = _signed_plastic_rate_d(y[TAU], y[GAP], P)
    _, ry, rt, rg = _signed_gap_rate_d(y[GAP], y[TAU], y[GP], P)
    JJ[:, :] = 0.0
    JJ[TAU, TAU], JJ[TAU, GP], JJ[TAU, GD] = cj, P[_G], -P[_G]
    JJ[GAP, TAU], JJ[GAP, GAP], JJ[GAP, GP] = -rt, cj - ry, -rg
    JJ[GP, TAU], JJ[GP, GAP], JJ[GP, GP] = -gt, -gy, 1.0
    JJ[GD, GD] = 1.0
    if C[0] != RATE:                     # mixture-stress control: gdot follows taubar
        JJ[GD, TAU] = 1.0 / P[_ETAF]
    JJ[STRAIN, GD], JJ[STRAIN, STRAIN] = -1.0, cj


@_jit
def events(t, y, ev, P, C):
    """Root functions: jamming gap, and strain - strain target."""
    ev[0] = y[GAP]
    ev[1] = y[STRAIN] - C[6] if np.isfinite(C[6]) else -1.0


# ------------------------------------------------------------------ eliminated (ODE) form
@_jit
def ode_rhs(t, y, out, P, C):
    """Right-hand side of the eliminated form, y = [taubar, gap, strain]."""
    g, _, _ = shear_rate(t, y[0], P, C)
    gp = signed_plastic_rate(y[0], y[1], P)
    out[0] = P[_G] * (g - gp)
    out[1] = signed_gap_rate(y[1], y[0], gp, P)
    out[2] = g


@_jit
def ode_jacobian(t, y, J, P, C):
    """d rhs/d y of :func:`ode_rhs` (exact, by complex step)."""
    g, gt_, _ = shear_rate(t, y[0], P, C)
    gp, gpt, gpy = _signed_plastic_rate_d(y[0], y[1], P)
    _, ry, rt, rg = _signed_gap_rate_d(y[1], y[0], gp, P)
    J[:, :] = 0.0
    J[0, 0], J[0, 1] = P[_G] * (gt_ - gpt), -P[_G] * gpy
    J[1, 0], J[1, 1] = rt + rg * gpt, ry + rg * gpy
    J[2, 0] = gt_


@_jit
def ode_residual(t, y, yp, res, P, C):
    """IDA residual of the eliminated form: yp - rhs."""
    ode_rhs(t, y, res, P, C)
    for i in range(3):
        res[i] = yp[i] - res[i]


@_jit
def ode_residual_jacobian(t, y, yp, cj, JJ, P, C):
    """IDA Jacobian of the eliminated form: cj I - d rhs/d y."""
    ode_jacobian(t, y, JJ, P, C)
    for i in range(3):
        for j in range(3):
            JJ[i, j] = -JJ[i, j]
        JJ[i, i] += cj


@_jit
def ode_events(t, y, ev, P, C):
    """Root functions of the eliminated form (same as :func:`events`)."""
    ev[0] = y[1]
    ev[1] = y[2] - C[6] if np.isfinite(C[6]) else -1.0
