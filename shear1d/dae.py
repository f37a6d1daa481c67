"""Method ``"dae"``: locked-mode Couette with the full Table 8 law as a smooth DAE on SUNDIALS IDA.

The ``"ida"`` method integrates the Table 8 local update as a rate; a flowing cell sits on the
update's switch between compaction and dilatant flow, where the Jacobian of that rate jumps. Here
the law is written in its continuous (dt -> 0) form, the plastic state an algebraic unknown and
the flow rule its equation (as the 0-D rheometer's DAE), one C1-smoothed compaction term the only
switch. Unknowns, interleaved cell by cell (half bandwidth :data:`BANDWIDTH`)::

    [v_0 if stress-driven], per cell j: s_rr, s_thth, s_rth, p, gap, x, then v_{j+1}

with s the deviatoric granular stress (s_zz = -s_rr - s_thth, sigma = s - p I), gap =
phi_m(f) - phi the jamming gap (f = f_jam - gap/(phi_j - phi_c)) and x the mixed inertial number
I_m continued below zero. In the co-rotating basis of :mod:`shear1d.kernels` (L = gdot e_th e_r,
D_kk = 0 locked), SI units::

    s'   = 2G D' + W s - s W - G gdot_p s/taubar       Table 8 (Jaumann, radial plastic flow)
    p'   = K (beta gdot_p + xi_2)                      Table 8 volumetric part (D_kk = 0)
    gap' = -(phi_j - phi_c) df/dt(f, taubar, gdot_p)   Table 8 structure law
    0    = taubar - Y(x) p                             the flow rule f_1 = 0 (algebraic in x)
    rho M_k v_k' = A_k tau_k - A_{k-1} tau_{k-1},  tau = sigma_rth + eta0 (1 + 5/2 phi) gdot

gdot_p is the positive root of ``p x^2 = rho_s d^2 gdot_p^2 + 2 eta0 gdot_p`` (Table 8's I_m),
I_v = eta0 gdot_p/p, beta = K3 (phi - phi_m/(1 + a x)), Y(x) = mu_p(I_v, x) + beta(x). Below
x = 0, Y is continued linearly and gdot_p = 0 (a cell under its yield stress loads elastically);
gdot_p grows as x^2, so the switch is C1. Compaction (f_3 <= 0, xi_2 <= 0, f_3 xi_2 = 0) at the
finite rate of Table 8's rule with K4 > 0 (K4 = 0 in the paper is the limit)::

    xi_2 = -s_w(zeta_cs - gdot_p)/K4 * (1 - p_floor/p),  zeta_cs = gdot_p(x = I_cs, p)

with I_cs = max(gap, 0)/(a phi) (zeta_cs > gdot_p exactly when beta < 0) and s_w(u) the
max(u, 0) of f_3's complementarity smoothed to C1 over w = COMPACTION_WIDTH zeta_cs; at a steady
critical state u = 0, so the smoothing leaves the steady states. (1 - p_floor/p) is the explicit
method's contact-pressure floor (:func:`shear1d.kernels.local_updates`): p > 0 always.

Parameters the paper does not have (our choice, checked against the explicit method on the fast
Fig. 3 case in tests/test_shear1d_dae.py): :data:`K4_REG` = 0.1 and :data:`COMPACTION_WIDTH` =
0.1. Needs ``mu1 + K3 (phi0 - phi_j) > 0`` (Y(0) > 0) and b > 0 unless mu_2 = mu_1, the table8
rules and the locked mode (:func:`check_material`, :class:`FullLawDAE`: ValueError). Results
come in the layout of :class:`shear1d.model.Couette`, so every analysis, file and figure applies.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rheology import laws
from rheology.local_update import COMPACTION, ELASTIC, SHEAR_FLOW
from rheology.numba_cache import guard

from . import kernels
from .model import Couette, interleaved

guard(__file__)                          # drop cached kernels if rheology's laws changed
_jit = nb.njit(cache=True, error_model="numpy")

#: Unknowns per cell (s_rr, s_thth, s_rth, p, gap, x) plus the cell's outer face velocity.
BLOCK = 7
#: Half bandwidth of the Jacobian: a face's momentum residual couples to the neighbouring faces,
#: one block (7 unknowns) away in the interleaved layout.
BANDWIDTH = 7
#: Regularising K4 of the compaction rule: an over-pressed loose cell relaxes to its critical
#: state at the rate K I_cs^2/(2 eta0 K4), 2e8 1/s for annular_shear at f = 0 (~1e7 times the fast
#: Fig. 3 shear rate); K4 = 1, 0.1, 0.01 give the same front speed within 0.05 %.
K4_REG = 0.1
#: Width of the C1 smoothing of the compaction switch, as a fraction of zeta_cs.
COMPACTION_WIDTH = 0.1
#: Absolute tolerance scale of x (an inertial number) [-].
X_SCALE = 1e-1

# parameter vector layout (see parameters())
(_PHI, _PHIC, _PHIJ, _A0, _AINF, _MU1, _MU2, _B, _ETA0, _RD2, _TSTAR, _INVB, _FM, _K0, _XIEPS,
 _G, _K, _K3, _ETAF, _K4, _PFLOOR, _WIDTH) = range(22)


def check_material(m, phi0: float) -> None:
    """Raise ValueError (one line) where the smooth form does not apply to material ``m`` at
    volume fraction ``phi0`` (see the module docstring): mu_1 + K3 (phi0 - phi_j) <= 0, or b = 0
    with mu_2 != mu_1, or the ``mpm_3d`` rules (the smooth form is Table 8's)."""
    if m.rules != "table8":
        raise ValueError(f"method 'dae' is the smooth form of the table8 rules, got rules = "
                         f"{m.rules!r} for {m.name}; use method 'ida' or 'explicit'")
    if m.mu_c + m.K3 * (phi0 - m.phi_j) <= 0.0:
        raise ValueError(f"method 'dae' needs mu_1 + K3 (phi0 - phi_j) > 0 (a positive yield "
                         f"ratio at rest), got {m.mu_c:g} + {m.K3:g} ({phi0:g} - {m.phi_j:g}) <= 0 "
                         f"for {m.name}: phi0 must exceed {m.phi_j - m.mu_c / m.K3:.6g}; use "
                         f"method 'ida' or 'explicit'")
    if (m.b or 0.0) <= 0.0 and m.mu2 != m.mu_c:
        raise ValueError(f"method 'dae' needs b > 0 when mu_2 != mu_1 (friction continuous at "
                         f"I_m = 0), got b = {m.b} for {m.name}; use method 'ida' or 'explicit'")


def parameters(problem: Couette, k4: float = K4_REG, width: float = COMPACTION_WIDTH
               ) -> np.ndarray:
    """Parameter vector of the per-cell law at the problem's (uniform, fixed) phi0; ValueError
    outside :func:`check_material`, for k4 <= 0 or a width outside (0, 1]."""
    m, phi = problem.material, problem.phi0
    check_material(m, phi)
    mu2 = m.mu2
    if not (k4 > 0.0 and np.isfinite(k4)):
        raise ValueError(f"k4 = {k4!r} must be > 0 (the regularising compaction K4)")
    if not (0.0 < width <= 1.0):
        raise ValueError(f"width = {width!r} must be in (0, 1]")
    return np.array([phi, m.phi_c, m.phi_j, m.a0, m.a_inf, m.mu_c, mu2, m.b or 0.0, m.eta0,
                     m.rho_s * m.d ** 2, m.tau_star,
                     laws.inv_eta_B(phi, m.phi_j, m.varphi1, m.alpha1, m.varphi2, m.alpha2),
                     laws.f_max(phi, m.phi_c, m.phi_j, m.Delta), m.K0, m.xi_eps, m.G, m.K, m.K3,
                     laws.fluid_viscosity(phi, m.eta0), k4, problem.contact_pressure, width],
                    dtype=float)


# ------------------------------------------------------------------ point-wise law
@_jit
def structure_of_gap(gap, P):
    """f = f_jam - gap/(phi_j - phi_c) [-]."""
    return (P[_PHIJ] - P[_PHI] - gap) / (P[_PHIJ] - P[_PHIC])


@_jit
def plastic_rate(x, p, P):
    """gdot_p >= 0 [1/s]: positive root of p x^2 = rho_s d^2 gdot^2 + 2 eta0 gdot (0 for x <= 0)."""
    if x <= 0.0 or p <= 0.0:
        return 0.0
    eta0 = P[_ETA0]
    c = p * x * x
    return c / (eta0 + np.sqrt(eta0 * eta0 + P[_RD2] * c))


@_jit
def yield_ratio(x, p, gap, P):
    """Y(x) = mu_p + beta of Table 8 at I_m = x >= 0; C1 linear continuation below 0 [-]."""
    f = structure_of_gap(gap, P)
    a = laws.dilatancy_a(f, P[_A0], P[_AINF])
    phi, phim, b, K3 = P[_PHI], P[_PHI] + gap, P[_B], P[_K3]
    mu1, dmu = P[_MU1], P[_MU2] - P[_MU1]
    if x <= 0.0:
        slope = (dmu / b if b > 0.0 else 0.0) + 1.25 * phi / a + K3 * phim * a
        return mu1 + K3 * (phi - phim) + slope * x
    eta0 = P[_ETA0]
    ivim = eta0 * x / (eta0 + np.sqrt(eta0 * eta0 + P[_RD2] * p * x * x))      # I_v / I_m
    mu = mu1 + (dmu * x / (x + b) if b > 0.0 else dmu) + 2.5 * phi * ivim / a
    return mu + K3 * (phi - phim / (1.0 + a * x))


@_jit
def smooth_positive(u, w):
    """max(u, 0) smoothed to C1 over (0, w): 0, u^2/(2w), u - w/2."""
    if u <= 0.0:
        return 0.0
    if u < w:
        return 0.5 * u * u / w
    return u - 0.5 * w


@_jit
def cell_law(srr, stt, srt, p, gap, x, P):
    """The law at one cell: (taubar, gdot_p, dp/dt [Pa/s], dgap/dt [1/s], f_1 residual [Pa],
    case code)."""
    szz = -srr - stt
    taubar = np.sqrt(0.5 * (srr * srr + stt * stt + szz * szz) + srt * srt)
    gp = plastic_rate(x, p, P)
    f = structure_of_gap(gap, P)
    a = laws.dilatancy_a(f, P[_A0], P[_AINF])
    phi, phim = P[_PHI], P[_PHI] + gap
    beta = P[_K3] * (phi - phim / (1.0 + a * max(x, 0.0)))
    i_cs = max(gap, 0.0) / (a * phi)
    zcs = plastic_rate(i_cs, p, P)
    comp = smooth_positive(zcs - gp, P[_WIDTH] * zcs + 1e-300)
    xi2 = -comp / P[_K4] * (1.0 - P[_PFLOOR] / p) if p > 0.0 else 0.0
    pdot = P[_K] * (beta * gp + xi2)
    gapdot = -(P[_PHIJ] - P[_PHIC]) * laws.structure_rate(f, taubar, gp, P[_FM], P[_TSTAR],
                                                          P[_INVB], P[_K0], P[_XIEPS])
    f1 = taubar - yield_ratio(x, p, gap, P) * p
    case = ELASTIC if x <= 0.0 else (COMPACTION if comp > 0.0 else SHEAR_FLOW)
    return taubar, gp, pdot, gapdot, f1, case


# ------------------------------------------------------------------ residual over the gap
@_jit
def residual(y, yp, u0, tau_wall, i_c, i_v, cg, w, A, M, A_wall, rho_face, P, res):
    """DAE residuals into ``res`` (see the module docstring); ``i_c[j]`` is the index of cell
    j's first unknown (s_rr), the others follow in the order s_thth, s_rth, p, gap, x."""
    n = i_c.shape[0]
    v = np.empty(n + 1)
    gdot = np.empty(n)
    tau = np.empty(n)
    vdot = np.empty(n + 1)
    kernels.face_velocities(y, i_v, u0, v)
    kernels.shear_rates(v, cg, w, gdot)
    G, etaf, scale = P[_G], P[_ETAF], 1.0 / P[_TSTAR]
    for j in range(n):
        k = i_c[j]
        srr, stt, srt, p, gap, x = y[k], y[k + 1], y[k + 2], y[k + 3], y[k + 4], y[k + 5]
        taubar, gp, pdot, gapdot, f1, _ = cell_law(srr, stt, srt, p, gap, x, P)
        g = gdot[j]
        relax = G * gp / taubar if taubar > 0.0 else 0.0
        res[k] = yp[k] - (-g * srt - relax * srr)
        res[k + 1] = yp[k + 1] - (g * srt - relax * stt)
        res[k + 2] = yp[k + 2] - (G * g + 0.5 * g * (srr - stt) - relax * srt)
        res[k + 3] = yp[k + 3] - pdot
        res[k + 4] = yp[k + 4] - gapdot
        res[k + 5] = f1 * scale
        tau[j] = srt + etaf * g
    kernels.momentum_rates(tau, A, M, rho_face, i_v, A_wall, tau_wall, vdot)
    for k in range(n + 1):
        if i_v[k] >= 0:
            res[i_v[k]] = yp[i_v[k]] - vdot[k]


@_jit
def to_couette(y, u0, i_c, i_v, cg, w, P, c_S, c_f, c_v, size, diag):
    """The DAE state in :class:`Couette`'s layout (index arrays c_S (n, 4), c_f, c_v) and the
    per-cell diagnostics (shear rate, plastic rate, pressure, case)."""
    n = i_c.shape[0]
    out = np.zeros(size)
    v = np.empty(n + 1)
    gdot = np.empty(n)
    kernels.face_velocities(y, i_v, u0, v)
    kernels.shear_rates(v, cg, w, gdot)
    for j in range(n):
        k = i_c[j]
        srr, stt, srt, p, gap, x = y[k], y[k + 1], y[k + 2], y[k + 3], y[k + 4], y[k + 5]
        _, gp, _, _, _, case = cell_law(srr, stt, srt, p, gap, x, P)
        out[c_S[j, 0]] = srr - p
        out[c_S[j, 1]] = stt - p
        out[c_S[j, 2]] = -srr - stt - p
        out[c_S[j, 3]] = srt
        out[c_f[j]] = structure_of_gap(gap, P)
        diag[j, 0] = gdot[j]
        diag[j, 1] = gp
        diag[j, 2] = p
        diag[j, 3] = case
    for k in range(n + 1):
        if c_v[k] >= 0:
            out[c_v[k]] = v[k]
    return out


@_jit
def solve_x(taubar, p, gap, P, x0):
    """x with taubar = Y(x) p (Newton with bisection safeguard; Y increases with x) [-]."""
    lo, hi = -1e3, 1e3
    x = x0
    for _ in range(200):
        r = taubar - yield_ratio(x, p, gap, P) * p
        if r > 0.0:
            lo = x
        else:
            hi = x
        h = 1e-7 * (abs(x) + 1e-3)
        d = -(yield_ratio(x + h, p, gap, P) - yield_ratio(x, p, gap, P)) * p / h
        xn = x - r / d if d < 0.0 else 0.5 * (lo + hi)
        if not lo < xn < hi:
            xn = 0.5 * (lo + hi)
        if abs(xn - x) <= 1e-14 * (abs(x) + 1e-12):
            return xn
        x = xn
    return x


# ------------------------------------------------------------------ the problem as a DAE
class FullLawDAE:
    """The full-law DAE of a locked :class:`Couette` problem (layout, residual, conversion).

    Parameters
    ----------
    problem : Couette (locked mode)
    k4, width : float
        Regularising K4 and smoothing width of the compaction rule (module docstring).

    Raises ValueError for a two-phase problem or a material outside the form's range.
    """

    def __init__(self, problem: Couette, k4: float = K4_REG, width: float = COMPACTION_WIDTH):
        if problem.two_phase:
            raise ValueError("method 'dae' (--method dae) is for mode 'locked' (--mode locked) "
                             "only: two-phase migration needs the Darcy flux of the two-phase "
                             "kernels; use method 'ida' or 'explicit'")
        self.pb = problem
        self.P = parameters(problem, k4, width)
        self.k4, self.width = float(self.P[_K4]), float(self.P[_WIDTH])
        n = problem.grid.n
        self.i_c, self.i_v, self.size = interleaved(n, BLOCK - 1, problem.stress_driven)
        self.i_p, self.i_gap, self.i_x = self.i_c + 3, self.i_c + 4, self.i_c + 5
        self.mt = problem.metrics()
        self.rho_face = problem.coefficients(np.full(n, problem.phi0))[0]
        lay = problem.layout()
        self.c_S, self.c_f, self.c_v = lay["i_S"], lay["i_f"], lay["i_v"]
        self.c_size = problem.size

    def residual(self, t: float, y: np.ndarray, yp: np.ndarray, res: np.ndarray) -> None:
        mt = self.mt
        residual(y, yp, self.pb.wall_velocity(t), self.pb.wall_traction(t), self.i_c, self.i_v,
                 mt["cg"], mt["w"], mt["A"], mt["M"], mt["A_wall"], self.rho_face, self.P, res)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """At rest: s = 0, p = contact pressure, f = 0, v = 0 inside the gap, x on the flow rule
        (taubar = 0: x = -Y(0)/Y'(0) < 0, no plastic flow), with consistent derivatives."""
        P = self.P
        y = np.zeros(self.size)
        gap0 = P[_PHIJ] - P[_PHI]
        p0 = self.pb.contact_pressure
        y[self.i_p] = p0
        y[self.i_gap] = gap0
        y[self.i_x] = solve_x(0.0, p0, gap0, P, -0.1)
        return y, self.consistent_yp(0.0, y)

    def consistent_yp(self, t: float, y: np.ndarray) -> np.ndarray:
        """y' of the differential unknowns from the residual at y' = 0; x' = 0 (x is algebraic:
        IDA uses its y' only to start its predictor)."""
        res = np.empty(self.size)
        self.residual(t, y, np.zeros(self.size), res)
        yp = -res
        yp[self.i_x] = 0.0
        return yp

    def algebraic(self) -> np.ndarray:
        return self.i_x.copy()

    def tolerances(self, rtol: float) -> np.ndarray:
        """Absolute tolerances: rtol times tau* (stresses, pressure), (phi_j - phi_c) (gap: f to
        rtol), X_SCALE (x, an inertial number) and the velocity scale (v)."""
        pb = self.pb
        atol = np.empty(self.size)
        atol[self.i_c[:, None] + np.arange(4)] = rtol * pb.stress_scale()
        atol[self.i_gap] = rtol * (self.P[_PHIJ] - self.P[_PHIC])
        atol[self.i_x] = X_SCALE * rtol
        atol[self.i_v[self.i_v >= 0]] = rtol * pb.velocity_scale()
        return atol

    def convert(self, t: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Couette-layout state, diagnostics (n, 4)) of a DAE state at time t."""
        diag = np.empty((self.pb.grid.n, kernels.NDIAG))
        yc = to_couette(np.asarray(y, dtype=float), self.pb.wall_velocity(t), self.i_c,
                        self.i_v, self.mt["cg"], self.mt["w"], self.P, self.c_S, self.c_f,
                        self.c_v, self.c_size, diag)
        return yc, diag
