"""Numba kernels of the 1-D Couette model: plain arrays in, plain arrays out.

Per cell the granular effective stress is stored as four components (sigma_rr, sigma_thth,
sigma_zz, sigma_rth) [Pa], tension positive, in the cylindrical basis (plane Couette: x -> theta,
y -> r). The granular law is *only* :func:`rheology.local_update.update_point` (Table 8, one
implicit step): the explicit scheme takes it as its step (as the paper's MPM does); the method of
lines (IDA) uses it as a rate, (U_delta(state) - state)/delta (:func:`ode_rhs`).

Velocity gradient in the local (co-rotating cylindrical) basis. For v = v_th(r) e_th + v_r(r) e_r
the cylindrical components of grad v are [[dv_r/dr, -v_th/r], [dv_th/dr, v_r/r]]; the -v_th/r
entry is the rotation of the local basis following a material point. Taking the stress in that
basis, the Jaumann rate reduces exactly to the one of simple shear with rate
gdot = r d(v_th/r)/dr, so the local update gets ``L = [[D_rr, 0, 0], [gdot, D_thth, 0], [0, 0, 0]]``
(plane: gdot = dv_x/dy, D_thth = 0). Radial advection of the cell state by the (Darcy) solid
velocity is neglected: the solid displacement over a run is micrometres, far below a cell.
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rheology import laws
from rheology.local_update import FAILED, NOUT, OUT_FIELDS, update_point
from rheology.numba_cache import guard

guard(__file__)                          # drop cached kernels if rheology's kernels changed
_jit = nb.njit(cache=True, error_model="numpy")

_OUT_F = OUT_FIELDS.index("f")
_OUT_GP = OUT_FIELDS.index("shear_rate_p")
_OUT_P = OUT_FIELDS.index("pressure")
_OUT_CASE = OUT_FIELDS.index("case")

#: Columns of the per-cell diagnostics array written by :func:`local_updates`.
DIAG_FIELDS = ("shear_rate", "plastic_shear_rate", "pressure", "case")
NDIAG = len(DIAG_FIELDS)


@_jit
def drive(t, amplitude, ramp):
    """Wall drive (speed [m/s] or stress [Pa]) at time t [s]: linear ramp over ``ramp`` seconds."""
    if ramp <= 0.0 or t >= ramp:
        return amplitude
    return amplitude * max(t, 0.0) / ramp


@_jit
def phase_coefficients(phi, eta0, d, rho_s, rho_f, two_phase, rho_face, eta_f, mobility):
    """Mixture density on the faces [kg/m^3], fluid viscosity eta0 (1 + 5/2 phi) per cell [Pa s]
    and, in two-phase mode, the Darcy mobility n^2/C on the faces [m^2/(Pa s)] (0 at the walls;
    Beetstra drag at Re = 0: Re = rho_f |w| d/eta0 ~ 1e-4 here)."""
    n = phi.shape[0]
    for j in range(n):
        eta_f[j] = laws.fluid_viscosity(phi[j], eta0)
    for k in range(n + 1):
        ph = phi[0] if k == 0 else (phi[n - 1] if k == n else 0.5 * (phi[k - 1] + phi[k]))
        rho_face[k] = ph * rho_s + (1.0 - ph) * rho_f
        mobility[k] = 0.0
        if two_phase and 0 < k < n:
            mobility[k] = (1.0 - ph) ** 2 / laws.drag_coefficient(ph, 0.0, eta0, d)


@_jit
def face_velocities(y, i_v, u0, v):
    """Shear velocity on every face: unknowns from ``y`` (i_v >= 0), else the wall values (face
    0 the moving wall, speed u0 when velocity-driven; the last face the fixed wall)."""
    n1 = v.shape[0]
    for k in range(n1):
        if i_v[k] >= 0:
            v[k] = y[i_v[k]]
        elif k == 0:
            v[k] = u0
        else:
            v[k] = 0.0


@_jit
def shear_rates(v, cg, w, gdot):
    """gdot_j = cg_j (v_{j+1} w_{j+1} - v_j w_j): r d(v/r)/dr (annular) or dv/dy (plane) [1/s]."""
    for j in range(gdot.shape[0]):
        gdot[j] = cg[j] * (v[j + 1] * w[j + 1] - v[j] * w[j])


@_jit
def solid_radial_velocity(S, phi, mobility, v, hoop_f, dx, drho, vs):
    """Cross-gap solid velocity on the faces from Darcy's law (two-phase mode) [m/s].

    With both phases incompressible, impermeable walls and the phases locked in the shear
    direction, the zero net volume flux and the radial balances of Table 8 (quasi-static, the
    drag time rho/C ~ 1e-7 s) give v_s = n^2/C [d sigma_rr/dr + (sigma_rr - sigma_thth)/r
    + phi (rho_s - rho_f) v_th^2/r]; ``mobility`` = n^2/C at the faces [m^2/(Pa s)], 0 at walls.
    """
    n = S.shape[0]
    vs[0] = 0.0
    vs[n] = 0.0
    for k in range(1, n):
        drive_ = (S[k, 0] - S[k - 1, 0]) / dx
        drive_ += hoop_f[k] * 0.5 * ((S[k, 0] - S[k, 1]) + (S[k - 1, 0] - S[k - 1, 1]))
        drive_ += 0.5 * (phi[k] + phi[k - 1]) * drho * v[k] * v[k] * hoop_f[k]
        vs[k] = mobility[k] * drive_


@_jit
def solid_strain_rates(vs, phi, dx, a, V, hoop_c, drr, dtt, phi_rate):
    """Solid D_rr, D_thth [1/s] and the conservative volume-fraction rate dphi/dt [1/s] per cell."""
    n = phi.shape[0]
    for j in range(n):
        drr[j] = (vs[j + 1] - vs[j]) / dx
        dtt[j] = hoop_c[j] * 0.5 * (vs[j] + vs[j + 1])
        flo = 0.5 * (phi[j - 1] + phi[j]) * vs[j] if j > 0 else 0.0
        fhi = 0.5 * (phi[j] + phi[j + 1]) * vs[j + 1] if j < n - 1 else 0.0
        phi_rate[j] = -(a[j + 1] * fhi - a[j] * flo) / V[j]


@_jit
def local_updates(S, f, phi, gdot, drr, dtt, dt, P, p_floor, S_out, f_out, diag):
    """Advance every cell's granular state by dt with the shared Table 8 local update.

    A cell whose pressure falls below ``p_floor`` [Pa] (separation, or compaction at rest) is
    given the isotropic contact pressure p_floor: the rate form of the IDA method needs the floor
    (its pressure, a rate over delta, can overshoot below zero). Returns the index of the first
    cell whose update failed, or -1.
    """
    sig = np.zeros((3, 3))
    L = np.zeros((3, 3))
    so = np.empty((3, 3))
    out = np.empty(NOUT)
    for j in range(S.shape[0]):
        sig[0, 0] = S[j, 0]
        sig[1, 1] = S[j, 1]
        sig[2, 2] = S[j, 2]
        sig[0, 1] = S[j, 3]
        sig[1, 0] = S[j, 3]
        L[0, 0] = drr[j]
        L[1, 1] = dtt[j]
        L[1, 0] = gdot[j]
        update_point(sig, L, phi[j], f[j], dt, P, so, out)
        if out[_OUT_CASE] == FAILED:
            return j
        p = out[_OUT_P]
        if p < p_floor:
            for i in range(3):
                so[i, i] += p - p_floor
            p = p_floor
        S_out[j, 0] = so[0, 0]
        S_out[j, 1] = so[1, 1]
        S_out[j, 2] = so[2, 2]
        S_out[j, 3] = 0.5 * (so[0, 1] + so[1, 0])
        f_out[j] = out[_OUT_F]
        diag[j, 0] = gdot[j]
        diag[j, 1] = out[_OUT_GP]
        diag[j, 2] = p
        diag[j, 3] = out[_OUT_CASE]
    return -1


@_jit
def momentum_rates(tau, A, M, rho_face, i_v, A_wall, tau_wall, vdot):
    """Shear-velocity rates on the unknown faces [m/s^2] (vdot indexed like the faces).

    Interior face k: rho M_k dv/dt = A_k tau_k - A_{k-1} tau_{k-1}. A stress-driven moving wall
    (i_v[0] >= 0) carries the half dual cell: rho M_0 dv/dt = A_0 tau_0 + A_wall tau_wall, where
    tau_wall > 0 is the traction the wall applies in the direction of its motion.
    """
    n = tau.shape[0]
    for k in range(1, n):
        vdot[k] = (A[k] * tau[k] - A[k - 1] * tau[k - 1]) / (rho_face[k] * M[k])
    vdot[0] = 0.0
    if i_v[0] >= 0:
        vdot[0] = (A[0] * tau[0] + A_wall * tau_wall) / (rho_face[0] * M[0])
    vdot[n] = 0.0


@_jit
def unpack_cells(y, i_S, i_f, i_phi, phi_fixed, S, f, phi):
    """Cell states from the unknown vector: stress S (n, 4), f, phi (phi_fixed when locked)."""
    for j in range(S.shape[0]):
        for c in range(4):
            S[j, c] = y[i_S[j, c]]
        f[j] = y[i_f[j]]
        phi[j] = y[i_phi[j]] if i_phi[j] >= 0 else phi_fixed[j]


@_jit
def cross_gap_kinematics(S, phi, v, cg, w, a, V, hoop_c, hoop_f, dx, eta0, d, rho_s, rho_f,
                         two_phase, gdot, drr, dtt, phi_rate, rho_face, eta_f, mobility, vs):
    """Everything the cells need from the faces: shear rates, phase coefficients and, in
    two-phase mode, the Darcy solid velocity, the solid strain rates and dphi/dt."""
    phase_coefficients(phi, eta0, d, rho_s, rho_f, two_phase, rho_face, eta_f, mobility)
    shear_rates(v, cg, w, gdot)
    if two_phase:
        solid_radial_velocity(S, phi, mobility, v, hoop_f, dx, rho_s - rho_f, vs)
        solid_strain_rates(vs, phi, dx, a, V, hoop_c, drr, dtt, phi_rate)


@_jit
def shear_momentum(S, eta_f, gdot, A, M, rho_face, i_v, A_wall, tau_wall, tau, vdot):
    """Mixture shear stress tau = sigma_rth + eta_f gdot per cell and the face accelerations."""
    for j in range(gdot.shape[0]):
        tau[j] = S[j, 3] + eta_f[j] * gdot[j]
    momentum_rates(tau, A, M, rho_face, i_v, A_wall, tau_wall, vdot)


@_jit
def _scratch(n):
    """Work arrays of the kernels: face arrays (v, vs, vdot, rho_face, mobility) and cell arrays
    (gdot, drr, dtt, phi_rate, eta_f, tau)."""
    return np.zeros((5, n + 1)), np.zeros((6, n))


@_jit
def ode_rhs(y, u0, tau_wall, i_S, i_f, i_phi, i_v, phi_fixed, cg, w, A, M, A_wall, a, V, hoop_c,
            hoop_f, dx, eta0, d, rho_s, rho_f, P, delta, p_floor, ydot, diag, work):
    """Time derivative of the unknown vector (method of lines) into ``ydot``: the granular rates
    are (U_delta(state) - state)/delta, U_delta the Table 8 local update over delta [s] at the
    current velocity gradient (a plastic relaxation of rate lambda proceeds at
    lambda/(1 + lambda delta); elastic response and steady states are exact). ``work``: scratch
    (n, 11). Returns the failed cell or -1."""
    n = i_f.shape[0]
    S = work[:, 0:4]
    S_out = work[:, 4:8]
    f = work[:, 8]
    f_out = work[:, 9]
    phi = work[:, 10]
    faces, cells = _scratch(n)
    v, vs, vdot, rho_face, mobility = faces[0], faces[1], faces[2], faces[3], faces[4]
    gdot, drr, dtt, phi_rate, eta_f, tau = cells[0], cells[1], cells[2], cells[3], cells[4], \
        cells[5]
    unpack_cells(y, i_S, i_f, i_phi, phi_fixed, S, f, phi)
    two_phase = i_phi[0] >= 0
    face_velocities(y, i_v, u0, v)
    cross_gap_kinematics(S, phi, v, cg, w, a, V, hoop_c, hoop_f, dx, eta0, d, rho_s, rho_f,
                         two_phase, gdot, drr, dtt, phi_rate, rho_face, eta_f, mobility, vs)
    bad = local_updates(S, f, phi, gdot, drr, dtt, delta, P, p_floor, S_out, f_out, diag)
    if bad >= 0:
        return bad
    for j in range(n):
        for c in range(4):
            ydot[i_S[j, c]] = (S_out[j, c] - S[j, c]) / delta
        ydot[i_f[j]] = (f_out[j] - f[j]) / delta
        if two_phase:
            ydot[i_phi[j]] = phi_rate[j]
    shear_momentum(S, eta_f, gdot, A, M, rho_face, i_v, A_wall, tau_wall, tau, vdot)
    for k in range(n + 1):
        if i_v[k] >= 0:
            ydot[i_v[k]] = vdot[k]
    return -1


@_jit
def explicit_steps(nsteps, t0, dt, amp, ramp, stress_driven, v, S, f, phi, cg, w, A, M, A_wall,
                   a, V, hoop_c, hoop_f, dx, eta0, d, rho_s, rho_f, P, p_floor, diag, two_phase):
    """``nsteps`` symplectic Euler steps of dt [s] from t0, updating v (faces), S, f, phi in
    place: (two-phase) Darcy flux and phi; the Table 8 local update of every cell at the velocity
    gradient of v^n; v^{n+1} from the divergence of the new stresses plus eta_f gdot^n (stability:
    :func:`shear1d.integrate.stable_time_step`). Returns (steps done, failed cell or -1); stops
    early at a state that is not finite."""
    n = f.shape[0]
    i_v = np.full(n + 1, -1)
    if stress_driven:
        i_v[0] = 0
    faces, cells = _scratch(n)
    vs, vdot, rho_face, mobility = faces[1], faces[2], faces[3], faces[4]
    gdot, drr, dtt, phi_rate, eta_f, tau = cells[0], cells[1], cells[2], cells[3], cells[4], \
        cells[5]
    S_out = np.empty_like(S)
    f_out = np.empty_like(f)
    for step in range(nsteps):
        t = t0 + step * dt
        if not stress_driven:
            v[0] = drive(t, amp, ramp)
        tau_w = drive(t, amp, ramp) if stress_driven else 0.0
        cross_gap_kinematics(S, phi, v, cg, w, a, V, hoop_c, hoop_f, dx, eta0, d, rho_s, rho_f,
                             two_phase, gdot, drr, dtt, phi_rate, rho_face, eta_f, mobility, vs)
        if two_phase:
            for j in range(n):
                phi[j] += dt * phi_rate[j]
        bad = local_updates(S, f, phi, gdot, drr, dtt, dt, P, p_floor, S_out, f_out, diag)
        if bad >= 0:
            return step, bad
        S[:, :] = S_out
        f[:] = f_out
        shear_momentum(S, eta_f, gdot, A, M, rho_face, i_v, A_wall, tau_w, tau, vdot)
        finite = True
        for k in range(n + 1):
            if i_v[k] >= 0 or (k > 0 and k < n):
                v[k] += dt * vdot[k]
                if not np.isfinite(v[k]) or abs(v[k]) > 1e30:
                    finite = False
        if not finite:
            return step + 1, -1
    if not stress_driven:
        v[0] = drive(t0 + nsteps * dt, amp, ramp)
    return nsteps, -1
