"""Method ``"dae"``: the locked-mode Couette problem with the reduced (critical-state) law, as a
smooth DAE on SUNDIALS IDA.

Why: the ``"ida"`` method integrates the full Table 8 local update as a rate,
``(U_delta(state) - state)/delta``; in flowing cells that state sits on the update's switch
between compaction and dilatant flow, so IDA sees a kinked right-hand side, re-evaluates its
Jacobian on about half the residual calls and its cost grows as cells^2.4 on the fast Fig. 3 case.
Here every cell carries the state of the 0-D rheometer DAE (paper Eqs. 35-37, the K -> inf limit of
Table 8 in simple shear), whose residual is smooth, coupled across the gap by the same momentum
balance as :mod:`shear1d.kernels`.

Unknowns, interleaved cell by cell (banded Jacobian, half bandwidth 4)::

    [v_0 if stress-driven], per cell j: taubar_j, gap_j, gdot_p_j, then v_{j+1} (not after the
    last cell: the fixed wall)

Equations (SI units; gdot_j = cg_j (v_{j+1} w_{j+1} - v_j w_j) = r d(v/r)/dr or dv/dy)::

    0 = taubar_j' - G (gdot_j - gdot_p_j)                       granular shear stress (elastic)
    0 = gap_j'    + (phi_j - phi_c) df/dt(f, |taubar|, |gdot_p|) Table 8 structure law
    0 = gdot_p_j  - sign(taubar) gdot_cs(|taubar_j|, gap_j)      flow rule at the critical state
    0 = rho M_k v_k' - (A_k tau_k - A_{k-1} tau_{k-1})           shear momentum, interior faces
    tau_j = taubar_j + eta0 (1 + 5/2 phi) gdot_j                mixture shear stress

with gap = phi_m(f) - phi the jamming gap (negative when jammed) and gdot_cs the critical-state
plastic rate of :func:`rheology.laws.critical_shear_rate`: Eq. (35) with grain inertia, multiplied
through by max(gap, 0)^2, i.e. ``A gdot_p^2 + eta0 gdot_p [2 mu* (a phi)^2 + 5/2 phi^2 y] =
taubar y^2``, y = max(gap, 0) (0 when jammed). A stress-driven moving wall carries the half dual
cell: ``rho M_0 v_0' = A_0 tau_0 + A_wall tau_wall``.

What the reduced law keeps and leaves out (against the full Table 8 update of ``"ida"`` and
``"explicit"``): it keeps the elastic shear response (G), the critical-state flow rule with its
friction mu*(gap), the dilatancy parameter a(f), grain inertia, the full structure law (Table 8,
with f_m(phi), eta_B(phi), K0, xi_eps) and the fluid's viscous stress. It leaves out the
granular pressure as a state: p is slaved to the critical state (K -> inf), so there is no
elastic volumetric response, no compaction or separation, no dilatancy-driven pressure transient
(dp/dt = K beta gdot_p) and no normal-stress differences (sigma_rr = sigma_thth = sigma_zz = -p);
the Jaumann rotation terms, which couple the shear stress to normal-stress differences, vanish
with them. The reported pressure is the critical-state one, ``p = |taubar|/(mu* + 5/2 eta0
y/(a^2 (gdot_p d^2 rho_s + 2 eta0)))`` (equal to :func:`rheology.laws.critical_pressure` where
the cell flows), which is |taubar|/mu_1 in a jammed cell: the reduced law leaves a jammed cell's
pressure undetermined above that yield bound, and the bound is what is reported. The 0-D
comparison of the two laws is the validation case ``shear1d_reduced_vs_full_law``.

Only the locked mode (phi fixed) is reduced this way: two-phase migration needs the pressure
gradient, which this law does not carry.

The Jacobian is SUNDIALS' banded difference quotient (2 x 4 + 1 residual calls per evaluation,
see :func:`solve_dae`); the results are returned in the layout of :class:`shear1d.model.Couette`
(stress components -p, -p, -p, taubar; f; face velocities) so every analysis, file and figure of
the other methods applies unchanged.
"""

from __future__ import annotations

import time

import numba as nb
import numpy as np

from rheology import laws
from rheology.local_update import ELASTIC, SHEAR_FLOW
from rheology.numba_cache import guard

from . import kernels
from .integrate import (_IDA_ROOT_RETURN, EVENTS, _Events, _result, check_state)
from .model import Couette

guard(__file__)                          # drop cached kernels if rheology's laws changed
_jit = nb.njit(cache=True, error_model="numpy")

#: Half bandwidth of the DAE's Jacobian (a face couples to tau of both cells and to both
#: neighbouring faces, 4 unknowns away in the interleaved layout).
BANDWIDTH = 4

# parameter vector layout (see parameters())
_PHI, _PHIC, _PHIJ, _A0, _AINF, _MU1, _MU2, _B, _ETA0, _D, _RHOS, _TSTAR, _INVB, _FM, _K0, \
    _XIEPS, _G, _ETAF = range(18)


def parameters(problem: Couette) -> np.ndarray:
    """Parameter vector of the per-cell reduced law at the problem's (uniform, fixed) phi0."""
    m, phi = problem.material, problem.phi0
    return np.array([phi, m.phi_c, m.phi_j, m.a0, m.a_inf, m.mu_c, m.mu2, m.b, m.eta0, m.d,
                     m.rho_s, m.tau_star,
                     laws.inv_eta_B(phi, m.phi_j, m.varphi1, m.alpha1, m.varphi2, m.alpha2),
                     laws.f_max(phi, m.phi_c, m.phi_j, m.Delta), m.K0, m.xi_eps, m.G,
                     laws.fluid_viscosity(phi, m.eta0)], dtype=float)


# ------------------------------------------------------------------ point-wise reduced law
@_jit
def structure_of_gap(gap, P):
    """f = f_jam - gap/(phi_j - phi_c) [-]."""
    return (P[_PHIJ] - P[_PHI] - gap) / (P[_PHIJ] - P[_PHIC])


@_jit
def plastic_rate(taubar, gap, P):
    """sign(taubar) gdot_cs(|taubar|, gap) [1/s]: Eq. (35) at the critical state, multiplied
    through by max(gap, 0)^2 (0 when jammed)."""
    s = 1.0 if taubar >= 0.0 else -1.0
    a = laws.dilatancy_a(structure_of_gap(gap, P), P[_A0], P[_AINF])
    return s * laws.critical_shear_rate(s * taubar, P[_PHI], max(gap, 0.0), a, P[_MU1],
                                        P[_MU2], P[_B], P[_ETA0], P[_D], P[_RHOS])


@_jit
def gap_rate(gap, taubar, gp, P):
    """d gap/dt = -(phi_j - phi_c) df/dt, Table 8's structure law on |taubar|, |gdot_p| [1/s]."""
    f = structure_of_gap(gap, P)
    return -(P[_PHIJ] - P[_PHIC]) * laws.structure_rate(f, abs(taubar), abs(gp), P[_FM],
                                                        P[_TSTAR], P[_INVB], P[_K0], P[_XIEPS])


@_jit
def critical_pressure(taubar, gap, gp, P):
    """Granular pressure of the critical state [Pa] (see the module docstring), >= 0."""
    y = max(gap, 0.0)
    a = laws.dilatancy_a(structure_of_gap(gap, P), P[_A0], P[_AINF])
    mu = laws.critical_friction(P[_PHI], y, a, P[_MU1], P[_MU2], P[_B])
    g = abs(gp)
    return abs(taubar) / (mu + 2.5 * P[_ETA0] * y / (a * a * (g * P[_D] ** 2 * P[_RHOS]
                                                                + 2.0 * P[_ETA0])))


# ------------------------------------------------------------------ residual over the gap
@_jit
def residual(y, yp, u0, tau_wall, i_tau, i_gap, i_gp, i_v, cg, w, A, M, A_wall, rho_face, P,
             res):
    """DAE residuals into ``res`` (see the module docstring), all in the interleaved layout."""
    n = i_tau.shape[0]
    v = np.empty(n + 1)
    gdot = np.empty(n)
    tau = np.empty(n)
    vdot = np.empty(n + 1)
    kernels.face_velocities(y, i_v, u0, v)
    kernels.shear_rates(v, cg, w, gdot)
    G, etaf = P[_G], P[_ETAF]
    for j in range(n):
        tb, gap, gp = y[i_tau[j]], y[i_gap[j]], y[i_gp[j]]
        res[i_tau[j]] = yp[i_tau[j]] - G * (gdot[j] - gp)
        res[i_gap[j]] = yp[i_gap[j]] - gap_rate(gap, tb, gp, P)
        res[i_gp[j]] = gp - plastic_rate(tb, gap, P)
        tau[j] = tb + etaf * gdot[j]
    kernels.momentum_rates(tau, A, M, rho_face, i_v, A_wall, tau_wall, vdot)
    for k in range(n + 1):
        if i_v[k] >= 0:
            res[i_v[k]] = yp[i_v[k]] - vdot[k]


@_jit
def to_couette(y, u0, i_tau, i_gap, i_gp, i_v, cg, w, P, c_S, c_f, c_v, size, diag):
    """The DAE state in :class:`Couette`'s layout (index arrays c_S (n, 4), c_f, c_v) and the
    per-cell diagnostics (shear rate, plastic rate, pressure, case)."""
    n = i_tau.shape[0]
    out = np.zeros(size)
    v = np.empty(n + 1)
    gdot = np.empty(n)
    kernels.face_velocities(y, i_v, u0, v)
    kernels.shear_rates(v, cg, w, gdot)
    for j in range(n):
        tb, gap, gp = y[i_tau[j]], y[i_gap[j]], y[i_gp[j]]
        p = critical_pressure(tb, gap, gp, P)
        for c in range(3):
            out[c_S[j, c]] = -p
        out[c_S[j, 3]] = tb
        out[c_f[j]] = structure_of_gap(gap, P)
        diag[j, 0] = gdot[j]
        diag[j, 1] = gp
        diag[j, 2] = p
        diag[j, 3] = SHEAR_FLOW if gap > 0.0 else ELASTIC
    for k in range(n + 1):
        if c_v[k] >= 0:
            out[c_v[k]] = v[k]
    return out


# ------------------------------------------------------------------ the problem as a DAE
class ReducedDAE:
    """The reduced-law DAE of a locked :class:`Couette` problem (layout, residual, conversion).

    Raises ValueError for a two-phase problem (the reduced law has no pressure to drive Darcy
    migration).
    """

    def __init__(self, problem: Couette):
        if problem.two_phase:
            raise ValueError("method 'dae' (reduced critical-state law) is for mode 'locked' "
                             "only: two-phase migration needs the granular pressure, which the "
                             "reduced law does not evolve; use method 'ida' or 'explicit'")
        self.pb = problem
        n = problem.grid.n
        i_tau, i_gap, i_gp = (np.empty(n, dtype=np.int64) for _ in range(3))
        i_v = np.full(n + 1, -1, dtype=np.int64)
        pos = 0
        if problem.stress_driven:
            i_v[0], pos = 0, 1
        for j in range(n):
            i_tau[j], i_gap[j], i_gp[j] = pos, pos + 1, pos + 2
            pos += 3
            if j < n - 1:
                i_v[j + 1], pos = pos, pos + 1
        self.i_tau, self.i_gap, self.i_gp, self.i_v, self.size = i_tau, i_gap, i_gp, i_v, pos
        self.P = parameters(problem)
        mt = problem.metrics()
        self.mt = mt
        self.rho_face = problem.coefficients(np.full(n, problem.phi0))[0]
        lay = problem.layout()
        self.c_S, self.c_f, self.c_v = lay["i_S"], lay["i_f"], lay["i_v"]
        self.c_size = problem.size

    # -- residual and state
    def residual(self, t: float, y: np.ndarray, yp: np.ndarray, res: np.ndarray) -> None:
        mt = self.mt
        residual(y, yp, self.pb.wall_velocity(t), self.pb.wall_traction(t), self.i_tau,
                 self.i_gap, self.i_gp, self.i_v, mt["cg"], mt["w"], mt["A"], mt["M"],
                 mt["A_wall"], self.rho_face, self.P, res)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """At rest (taubar = 0, f = 0, v = 0 inside the gap) with consistent derivatives."""
        y = np.zeros(self.size)
        y[self.i_gap] = self.P[_PHIJ] - self.P[_PHI]          # f = 0
        return y, self.consistent_yp(0.0, y)

    def consistent_yp(self, t: float, y: np.ndarray) -> np.ndarray:
        """y' of the differential unknowns from the residual at y' = 0; the algebraic plastic
        rate's derivative by a directional difference along (taubar', gap')."""
        res = np.empty(self.size)
        self.residual(t, y, np.zeros(self.size), res)
        yp = -res
        h = 1e-7 * max(self.pb.flow_time(), 1e-12)
        y2 = y + h * yp
        gp = np.array([plastic_rate(y[a], y[b], self.P) for a, b in zip(self.i_tau, self.i_gap)])
        gp2 = np.array([plastic_rate(y2[a], y2[b], self.P)
                        for a, b in zip(self.i_tau, self.i_gap)])
        yp[self.i_gp] = (gp2 - gp) / h
        return yp

    def algebraic(self) -> np.ndarray:
        return self.i_gp.copy()

    def tolerances(self, rtol: float) -> np.ndarray:
        """Absolute tolerances: rtol times tau* (stress), (phi_j - phi_c) (gap, i.e. f to rtol),
        the velocity scale (v) and the velocity scale over the gap width (plastic rate)."""
        pb = self.pb
        atol = np.empty(self.size)
        atol[self.i_tau] = rtol * pb.stress_scale()
        atol[self.i_gap] = rtol * (self.P[_PHIJ] - self.P[_PHIC])
        atol[self.i_gp] = rtol * pb.velocity_scale() / pb.grid.gap
        atol[self.i_v[self.i_v >= 0]] = rtol * pb.velocity_scale()
        return atol

    def convert(self, t: float, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Couette-layout state, diagnostics (n, 4)) of a DAE state at time t."""
        diag = np.empty((self.pb.grid.n, kernels.NDIAG))
        yc = to_couette(np.asarray(y, dtype=float), self.pb.wall_velocity(t), self.i_tau,
                        self.i_gap, self.i_gp, self.i_v, self.mt["cg"], self.mt["w"], self.P,
                        self.c_S, self.c_f, self.c_v, self.c_size, diag)
        return yc, diag


class _DAEEvents(_Events):
    """The events of :mod:`shear1d.integrate` evaluated on the converted state."""

    def __init__(self, problem: Couette, dae: ReducedDAE):
        super().__init__(problem)
        self.dae = dae

    def values(self, t, y):
        if len(y) == self.dae.size:
            y = self.dae.convert(t, y)[0]
        return super().values(t, y)


def solve_dae(problem, times, rtol, stop_on, outs, ck, max_step, max_order, bar, stop_hook):
    """Integrate with IDA (banded difference-quotient Jacobian, BDF order <= max_order); the
    same outputs, events, checkpoints and stats as :func:`shear1d.integrate.solve` with
    ``method="ida"`` (called from there with ``method="dae"``). Raises RuntimeError with
    diagnostics when IDA fails or a state is unphysical."""
    from sksundae.ida import IDA

    dae = ReducedDAE(problem)
    n = problem.grid.n
    events = _DAEEvents(problem, dae)
    events.times = outs.events.times
    outs.events = events

    def stats(counters):
        return dict(nfev=int(counters[0]), njev=int(counters[1]), rtol=rtol,
                    bandwidth=BANDWIDTH)

    wall0 = time.perf_counter()
    if ck is None:
        y0, yp0 = dae.initial_state()
        yc, dg = dae.convert(0.0, y0)
        outs.add(0.0, yc, dg, (0, 0, 0), dict(y=y0.copy(), yp=yp0.copy()))
        base = np.zeros(3)
    else:
        y0, yp0 = ck["y"], ck["yp"]
        if y0.shape != (dae.size,):
            raise ValueError("--resume: the checkpoint's DAE state does not match this grid")
        base = np.asarray(ck["counters"], dtype=float)
        outs.rows[-1] = outs.rows[-1][:4] + (dict(y=y0, yp=yp0),)
        if bool(ck["finished"]):
            return _result(problem, "dae", outs, wall0, stats(base))
    t0 = outs.t_last
    i_next = int(np.searchsorted(times, t0, side="right"))
    opts = dict(rtol=rtol, atol=dae.tolerances(rtol), linsolver="band", lband=BANDWIDTH,
                uband=BANDWIDTH, max_num_steps=500000, max_step=max_step, max_order=max_order,
                algebraic_idx=dae.algebraic())
    if events.active:
        opts.update(eventsfn=events.ida_function(), num_events=len(EVENTS))
    solver = IDA(dae.residual, **opts)
    solver.init_step(t0, y0, yp0)
    bar.to(t0)
    seen, stopped = 0, False
    counters = base.copy()
    try:
        for t_target in times[i_next:]:
            while True:
                sol = solver.step(float(t_target))
                counters = base + np.array([sol.nfev, sol.njev, 0.0])
                if sol.status == _IDA_ROOT_RETURN:
                    seen, fired = events.record_roots(sol, seen)
                    stopped = stopped or any(name in stop_on for name in fired)
                    if stopped:
                        break
                    continue
                if not sol.success:
                    yc, _ = dae.convert(sol.t, sol.y)
                    st = problem.unpack(yc, sol.t)
                    raise RuntimeError(
                        f"IDA (method dae) failed at t = {sol.t:.6g} s (target {t_target:.6g} "
                        f"s): {sol.message} (status {sol.status}); {n} cells, rtol {rtol:g}; "
                        f"max f = {st['f'].max():.6g}, max |taubar| = "
                        f"{np.abs(sol.y[dae.i_tau]).max():.6g} Pa")
                break
            t_now = float(sol.t)
            yc, diag = dae.convert(t_now, sol.y)
            check_state(problem, t_now, yc, diag, f_tol=100 * rtol)
            outs.add(t_now, yc, diag, counters, dict(y=sol.y.copy(), yp=sol.yp.copy()))
            bar.to(t_now)
            last = stopped or t_target == times[-1]
            if last or outs.due():
                outs.save(finished=last, wall=outs.wall_before + time.perf_counter() - wall0)
            if stop_hook is not None and not last:
                stop_hook(t_now)
            if stopped:
                break
    except KeyboardInterrupt:
        raise outs.interrupted(outs.wall_before + time.perf_counter() - wall0) from None
    return _result(problem, "dae", outs, wall0, stats(counters))
