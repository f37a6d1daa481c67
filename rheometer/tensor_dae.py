"""The Table 8 granular law in homogeneous simple shear as a DAE on IDA: the dt -> 0 limit of the
material-point mode, against which its time-step error is measured.

With ``L = [[0, gdot, 0], [0, e, 0], [0, 0, 0]]`` (D' = D - e/3 I, spin W_xy = gdot/2), deviatoric
stress s, pressure p (sigma = s - p I), the continuous law the local update discretises is::

    s'   = 2G D' + W s - s W - G gdot_p s / taubar           (Jaumann rate, radial plastic flow)
    p'   = -K e + K (beta gdot_p + xi_2)                       (volumetric, Eq. 10)
    f'   = df/dt(f, taubar, gdot_p, phi)                       (Table 8)
    phi' = -phi e                                              (mass conservation)

with one of two flowing regimes, exactly as the local update chooses them:

- dilatant shear flow (xi_2 = 0): f_1 = taubar - (mu_p(I_v, I_m) + beta) p = 0 fixes gdot_p
  (algebraic); beta = K3 (phi - phi_m/(1 + a I_m));
- shear flow + compaction (phi = phi_eq, beta = 0): gdot_p = gdot_cs(taubar) and
  p = p_cs(gdot_p) (both algebraic, the critical state); xi_2 <= 0 follows from p'.

Volume control: e = 0, phi fixed. Pressure control: p = p_target; in the dilatant regime
e = beta gdot_p; in the compaction regime e keeps p_cs(gdot_cs(taubar, f, phi), f, phi) = p_target
through its time derivative (index reduced; the drift is checked to stay at solver tolerance).

The regime is chosen at the start and after every switch by one local update of the material-point
mode with a tiny step (the discrete rule itself); IDA event functions stop the solve where the
regime changes (beta falls to 0 in dilatant flow, xi_2 rises to 0 in compaction). Jamming or
separation ends the reference with a ``RuntimeError``: it covers flowing states only.
"""

from __future__ import annotations

import numba as nb
import numpy as np
import pandas as pd

import rheology
from rheology import laws
from runkit.params import check_positive
from rheology.local_update import CASE_NAMES, COMPACTION, NOUT, SHEAR_FLOW
from rheology.materials import KERNEL_FIELDS
from rheology.numba_cache import guard
from runkit.ida import IDAFailed, Solver

from .material_point import initial_point, local_step, point_parameters, pressure_step

guard(__file__)                          # drop cached kernels if rheology's laws changed
_jit = nb.njit(cache=True, error_model="numpy")

SXX, SYY, SZZ, SXY, PP, FF, PHI, GP, EE = range(9)
NV = 9
# positions in the kernel parameter vector of rheology (rheology.kernel_parameters)
(_PHIC, _PHIJ, _A0, _AINF, _MU1, _MU2, _B, _TSTAR, _ETA0, _V1, _AL1, _V2, _AL2, _DELTA, _XIEPS,
 _K0, _G, _K, _RHOS, _D, _K3) = (KERNEL_FIELDS.index(k) for k in (
    "phi_c", "phi_j", "a0", "a_inf", "mu_c", "mu_2", "b", "tau_star", "eta0", "varphi1", "alpha1",
    "varphi2", "alpha2", "Delta", "xi_eps", "K0", "G", "K", "rho_s", "d", "K3"))
DILATANT, COMPACTING = 0, 1
_H = 1e-30


@_jit
def _taubar(y):
    return np.sqrt(0.5 * (y[SXX] ** 2 + y[SYY] ** 2 + y[SZZ] ** 2 + 2.0 * y[SXY] ** 2))


@_jit
def _gap(f, phi, P):
    return np.maximum(laws.phi_m(f, P[_PHIC], P[_PHIJ]) - phi, 0.0)


@_jit
def _critical_pressure_of(taubar, f, phi, P):
    """p_cs(gdot_cs(taubar, f, phi), f, phi) [Pa] (real or complex arguments)."""
    y = _gap(f, phi, P)
    a = laws.dilatancy_a(f, P[_A0], P[_AINF])
    g = laws.critical_shear_rate(taubar, phi, y, a, P[_MU1], P[_MU2], P[_B], P[_ETA0], P[_D],
                                 P[_RHOS])
    return laws.critical_pressure(g, phi, y, a, P[_ETA0], P[_D], P[_RHOS])


@_jit
def _residual(t, y, yp, res, P, Q):
    """Q = [gdot, control (0 volume, 1 pressure), regime, p_target]."""
    gdot, ctrl, regime, p_target = Q[0], Q[1], Q[2], Q[3]
    G, K, K0, K3 = P[_G], P[_K], P[_K0], P[_K3]
    eta0, d, rho_s = P[_ETA0], P[_D], P[_RHOS]
    tau = _taubar(y)
    f, phi, g, e, p = y[FF], y[PHI], y[GP], y[EE], y[PP]
    k = G * g / max(tau, 1e-300)
    res[SXX] = yp[SXX] - (-2.0 * G * e / 3.0 + gdot * y[SXY] - k * y[SXX])
    res[SYY] = yp[SYY] - (4.0 * G * e / 3.0 - gdot * y[SXY] - k * y[SYY])
    res[SZZ] = yp[SZZ] - (-2.0 * G * e / 3.0 - k * y[SZZ])
    res[SXY] = yp[SXY] - (G * gdot + 0.5 * gdot * (y[SYY] - y[SXX]) - k * y[SXY])
    fm = laws.f_max(phi, P[_PHIC], P[_PHIJ], P[_DELTA])
    invB = laws.inv_eta_B(phi, P[_PHIJ], P[_V1], P[_AL1], P[_V2], P[_AL2])
    res[FF] = yp[FF] - laws.structure_rate(f, tau, g, fm, P[_TSTAR], invB, K0, P[_XIEPS])
    res[PHI] = yp[PHI] + phi * e
    gap = _gap(f, phi, P)
    a = laws.dilatancy_a(f, P[_A0], P[_AINF])
    if regime == DILATANT:
        I, Iv, Im = laws.inertial_numbers(g, p, eta0, d, rho_s)
        phim = laws.phi_m(f, P[_PHIC], P[_PHIJ])
        beta = laws.dilation_angle(phi, laws.phi_equilibrium(phim, a, Im), K3)
        mu = laws.friction(Iv, Im, phi, a, P[_MU1], P[_MU2], P[_B])
        res[GP] = tau - (mu + beta) * p
        if ctrl == 0:
            res[PP] = yp[PP] - K * beta * g
            res[EE] = e
        else:
            res[PP] = p - p_target
            res[EE] = e - beta * g
    else:
        res[GP] = g - laws.critical_shear_rate(tau, phi, gap, a, P[_MU1], P[_MU2], P[_B], eta0, d,
                                               rho_s)
        res[PP] = p - laws.critical_pressure(g, phi, gap, a, eta0, d, rho_s)
        if ctrl == 0:
            res[EE] = e
        else:                     # d/dt p_cs(taubar, f, phi) = 0, by complex-step partials
            taup = (y[SXX] * yp[SXX] + y[SYY] * yp[SYY] + y[SZZ] * yp[SZZ]
                    + 2.0 * y[SXY] * yp[SXY]) / (2.0 * max(tau, 1e-300))
            dq_t = _critical_pressure_of(tau + 1j * _H, f + 0j, phi + 0j, P).imag / _H
            dq_f = _critical_pressure_of(tau + 0j, f + 1j * _H, phi + 0j, P).imag / _H
            dq_p = _critical_pressure_of(tau + 0j, f + 0j, phi + 1j * _H, P).imag / _H
            res[EE] = (dq_t * taup + dq_f * yp[FF] + dq_p * yp[PHI]) / p_target


@_jit
def _events(t, y, yp, ev, P, Q):
    """[regime switch, jamming gap, pressure]: beta (dilatant) or -xi_2 (compaction)."""
    ctrl, regime = Q[1], Q[2]
    f, phi, g, p = y[FF], y[PHI], y[GP], y[PP]
    a = laws.dilatancy_a(f, P[_A0], P[_AINF])
    if regime == DILATANT:
        I, Iv, Im = laws.inertial_numbers(g, max(p, 1e-300), P[_ETA0], P[_D], P[_RHOS])
        phim = laws.phi_m(f, P[_PHIC], P[_PHIJ])
        ev[0] = laws.dilation_angle(phi, laws.phi_equilibrium(phim, a, Im), P[_K3])
    else:
        ev[0] = -(yp[PP] / P[_K] + y[EE]) if ctrl == 0 else -y[EE]
    ev[1] = laws.phi_m(f, P[_PHIC], P[_PHIJ]) - phi
    ev[2] = p


def _probe(sig, phi, f, gdot, dt, ctrl, p_target, m, P):
    """Regime and algebraic guesses from one local update with a tiny step (the discrete rule)."""
    sig_out = np.empty((3, 3))
    out = np.zeros(NOUT)
    if ctrl == 0:
        local_step(sig, phi, f, gdot, 0.0, dt, P, sig_out, out)
        e = 0.0
    else:
        e, ok = pressure_step(sig, phi, f, gdot, 0.0, dt, p_target, m.K, P, sig_out, out)
        if not ok:
            raise RuntimeError("tensor reference: no dilation rate holds the pressure at the start")
    case = int(out[12])
    if case not in (SHEAR_FLOW, COMPACTION):
        raise RuntimeError(f"tensor reference covers flowing states only; the local update is in "
                           f"case {CASE_NAMES.get(case, case)}")
    return (DILATANT if case == SHEAR_FLOW else COMPACTING), out[1], e


def tensor_reference(material, phi: float, rate: float, t_end: float, *, control="volume",
                     pressure=None, stress0=None, f0=None, G=None, K=None, K0=None,
                     times=None, rtol: float = 1e-10) -> pd.DataFrame:
    """IDA solution of the continuous Table 8 law in homogeneous simple shear.

    Same arguments as :func:`rheometer.material_point.simple_shear_point` (start from the steady
    state at ``stress0``, which it requires), plus output ``times`` [s] and the IDA ``rtol``.
    Returns ``time_s, shear_stress_Pa`` (sigma_xy), ``granular_shear_stress_Pa,
    granular_pressure_Pa, N1_Pa, N2_Pa, f, phi, plastic_shear_rate_per_s, dilation_rate_per_s,
    regime``; ``attrs["switches"]`` lists the regime changes.
    """
    m0 = rheology.get_material(material)
    m, P = point_parameters(m0, G, K, K0)
    if stress0 is None:
        raise ValueError("the tensor reference starts from a steady state: give stress0 [Pa]")
    ctrl = 0 if control == "volume" else 1
    if ctrl and pressure is None:
        raise ValueError("pressure control needs the imposed granular pressure [Pa]")
    p_target = float(check_positive("pressure [Pa]", pressure)) if ctrl else 0.0
    sig, f = initial_point(m, phi, stress0=stress0, f0=f0)
    times = np.linspace(0.0, t_end, 201) if times is None else np.asarray(times, dtype=float)
    y = np.zeros(NV)
    y[SXX], y[SYY], y[SZZ], y[SXY] = 0.0, 0.0, 0.0, sig[0, 1]
    y[PP], y[FF], y[PHI] = -sig[0, 0], f, phi
    t0, rows, switches = float(times[0]), [], []
    dt_probe = 1e-9 * max(t_end, 1e-300)
    ended = None                         # the regime whose switch event ended the last segment
    while True:
        s3 = _stress(y)
        regime, g_guess, e_guess = _probe(s3, y[PHI], y[FF], rate, dt_probe, ctrl, p_target, m,
                                          P)
        if regime == ended:
            # exactly at the switch (beta or xi_2 crossing 0) the one-step probe may land on
            # either side; the event says the old regime's condition failed: take the other
            regime = COMPACTING if ended == DILATANT else DILATANT
        y[GP], y[EE] = g_guess, e_guess
        if ctrl:
            y[PP] = p_target
        if regime == COMPACTING:
            y[PP] = float(_critical_pressure_of(_taubar(y), y[FF], y[PHI], P))
        Q = np.array([rate, ctrl, regime, p_target])
        alg = [GP, EE] + ([PP] if (regime == COMPACTING or ctrl) else [])

        grid = np.concatenate([[t0], times[times > t0 * (1 + 1e-14) + 1e-300]])
        solver = Solver(lambda t, yy, yyp, res: _residual(t, yy, yyp, res, P, Q), rtol=rtol,
                        atol=1e-3 * rtol * _scales(y), algebraic_idx=alg, calc_initcond="yp0",
                        calc_init_dt=1e-6 * t_end, max_num_steps=500_000,
                        events=lambda t, yy, yyp, ev: _events(t, yy, yyp, ev, P, Q),
                        names=("switch", "jam", "separation"), direction=[-1] * 3, stop=[True] * 3)
        try:
            sol, _ = solver.solve(grid, y, np.zeros(NV))
        except IDAFailed as exc:
            raise RuntimeError(f"tensor reference: {exc}") from None
        keep = np.isin(sol.t, times)
        for ti, yi in zip(sol.t[keep], sol.y[keep]):
            if not rows or ti > rows[-1][0]:
                rows.append((ti, *yi, regime))
        y, t0 = sol.y[-1].copy(), float(sol.t[-1])
        if sol.t_events is None or sol.t_events[-1] != sol.t[-1] or t0 >= times[-1]:
            break
        which = int(np.flatnonzero(sol.i_events[-1])[0])
        if which == 1:
            raise RuntimeError(f"tensor reference: the point jams at t = {t0:.6g} s "
                               f"(phi >= phi_m(f)); it covers flowing states only")
        if which == 2:
            raise RuntimeError(f"tensor reference: the pressure vanishes at t = {t0:.6g} s")
        switches.append((t0, "compaction" if regime == DILATANT else "dilatant shear flow"))
        ended = regime
    arr = np.array(rows)
    s = arr[:, 1:5]
    p = arr[:, 1 + PP]
    df = pd.DataFrame({
        "time_s": arr[:, 0], "shear_stress_Pa": s[:, 3],
        "granular_shear_stress_Pa": _taubar.py_func(arr[:, 1:].T),
        "granular_pressure_Pa": p, "N1_Pa": s[:, 0] - s[:, 1], "N2_Pa": s[:, 1] - s[:, 2],
        "f": arr[:, 1 + FF], "phi": arr[:, 1 + PHI], "plastic_shear_rate_per_s": arr[:, 1 + GP],
        "dilation_rate_per_s": arr[:, 1 + EE],
        "regime": np.where(arr[:, -1] == DILATANT, "shear flow", "shear flow + compaction")})
    if ctrl:
        df.attrs["pressure_drift"] = float(np.max(np.abs(p - p_target)) / p_target)
    df.attrs["switches"] = switches
    return df


def _stress(y) -> np.ndarray:
    s = np.zeros((3, 3))
    s[0, 0], s[1, 1], s[2, 2] = y[SXX] - y[PP], y[SYY] - y[PP], y[SZZ] - y[PP]
    s[0, 1] = s[1, 0] = y[SXY]
    return s


def _scales(y) -> np.ndarray:
    tau = max(abs(y[SXY]), abs(y[PP]), 1e-300)
    return np.array([tau, tau, tau, tau, tau, 1.0, 1.0, max(abs(y[GP]), 1e-300), 1.0])
