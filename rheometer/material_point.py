"""Material-point mode: the full Table 8 local update driven through homogeneous simple shear.

This is where the tensor law that ``shear1d`` and ``mpm2d`` use is verified in 0-D. Each time step
calls :func:`rheology.local_update.update_point` (the shared numba kernel; nothing of the law is
re-implemented here) with the velocity gradient of simple shear in the x-y plane::

    L = [[0, gdot, 0],
         [0, e,    0],
         [0, 0,    0]]

- volume-controlled: ``e = 0``, phi fixed;
- pressure-controlled: the dilation rate ``e`` is found every step (bracketed secant/bisection on
  the step's end pressure) so that the granular pressure equals the imposed one, and the volume
  fraction follows mass conservation implicitly, ``phi_{n+1} = phi_n / (1 + e dt)``, the value
  the step is computed with.

The scheme is first order in dt (backward-Euler plastic correction, explicit Jaumann spin,
structure staggered after the stress). Its steady state is that of the continuous Jaumann law
exactly: sin(theta) = taubar/G, sigma_xy = taubar cos(theta), N1 = 2 taubar^2/G, and Eqs. (1)-(2)
hold at the plastic rate gdot_p = gdot cos(theta) (so up to O((taubar/G)^2)).

Sub-stepping (safe at any rate). Each step dt is split into n equal local updates of h = dt/n:

- explicit spin: the update rotates the stress with (1 + h W) instead of exp(h W); in the
  (sigma_xx - sigma_yy, sigma_xy) plane that is the rotation by the shear strain x = gdot h times
  sqrt(1 + x^2). A flowing update returns the stress radially to its yield value, so only the
  direction error O(x) remains: x <= 0.01 (:data:`STRAIN_PER_SUBSTEP`). An unyielded (elastic)
  update keeps the spurious growth, exp(gamma x/2) over a strain gamma: a step with an elastic
  sub-step is redone with x <= 2 SPIN_GROWTH/(gdot t_end) (1% over the whole run).
- cancellation: the update forms taubar = tau* - G h gdot_p, which keeps a relative precision of
  eps G h gdot_p/taubar; a step where that ratio exceeds :data:`Q_MAX` = 1e6 (2e-10 relative) is
  redone with proportionally more sub-steps;
- a sub-step that fails (bracketed solve, pressure solve, yield check) is redone with twice as
  many sub-steps.

A run that would need more than :data:`MAX_SUBSTEPS` (2e7) updates is refused up front (the
strain gdot t_end <= 2e5) or ends at the step that needs them (its rows before kept,
:mod:`rheology.run_end`).

Start from a steady state (``stress0``) or from rest under an isotropic contact pressure
(``pressure0`` >= 0; 0 is the stress-free point, which shear sets flowing through its dilatancy).
"""

from __future__ import annotations

import numba as nb
import numpy as np
import pandas as pd

import math

import rheology
from runkit import limits as physical
from runkit.limits import PHI_MIN, le, lt
from runkit.params import Param, check_nonnegative, check_positive
from rheology.elastic import past_elastic_limit
from rheology.local_update import (CASE_NAMES, COMPACTION, ELASTIC, FAILED, NOUT, OUT_FIELDS,
                                   SHEAR_FLOW, update_point)
from rheology.materials import Material
from rheology.numba_cache import guard
from rheology.run_end import EndedEarly, RunEnd

from . import limits
from .transient import skeleton

guard(__file__)                          # drop cached kernels if rheology's laws changed
_jit = nb.njit(cache=True, error_model="numpy")

#: Default bulk modulus relative to G where the material has none: K/G of Tables 4-7 (8.3/3.8).
K_OVER_G = 8.3 / 3.8
#: Recorded per output row: time, 3x3 stress (xx, yy, zz, xy), phi, dilation rate, then OUT_FIELDS.
_REC = 7
_OF = {name: _REC + i for i, name in enumerate(OUT_FIELDS)}
#: Return codes of the stepping kernel.
OK, UPDATE_FAILED, PRESSURE_FAILED, NOT_FINITE, YIELD_VIOLATED, CANCELLATION, TOO_MANY = range(7)
#: Sub-stepping bounds (derived in :func:`simple_shear_point`): the shear strain of one
#: sub-step (the explicit Jaumann spin) ...
STRAIN_PER_SUBSTEP = 1e-2
#: ... and the spurious growth of an unyielded (elastic) stress over the whole run, gdot t_end
#: x/2 <= SPIN_GROWTH with x = gdot h the sub-step's strain.
SPIN_GROWTH = 1e-2
#: Largest G h gdot_p/taubar (the trial stress removed by the plastic correction, relative to
#: what remains): taubar = tau* - G h gdot_p keeps ~eps Q_MAX relative precision (2e-10).
Q_MAX = 1e6
#: Most sub-steps of one run (about 10 s of computing) and of one output step.
MAX_SUBSTEPS = 20_000_000
MAX_SUBSTEPS_PER_STEP = 1e9
_MAXIT = 200
#: Largest accepted yield-function residual |f_1|/(taubar + mu_p p) of a flowing step, and
#: pressure mismatch |p - p_target|/p_target of a pressure-controlled step.
YIELD_TOL = 1e-6
PRESSURE_TOL = 1e-9


@_jit
def yield_residual(out):
    """|f_1|/(taubar + mu_p p) of a flowing local update (0 for the other cases).

    A flowing step must end on the yield surface, f_1 = taubar - (mu_p + beta) p = 0; the driver
    checks it so that an inaccurate solve of the shared kernel is reported, not propagated.
    """
    case = out[12]
    if case != SHEAR_FLOW and case != COMPACTION:
        return 0.0
    taubar, p, mu, beta = out[10], out[11], out[4], out[8]
    return abs(taubar - (mu + beta) * p) / max(taubar + mu * p, 1e-300)


@_jit
def local_step(sig, phi, f, gdot, e, dt, P, sig_out, out):
    """One local update of simple shear with dilation rate e; returns phi at the end of the step."""
    L = np.zeros((3, 3))
    L[0, 1] = gdot
    L[1, 1] = e
    phi_new = phi / (1.0 + e * dt)
    update_point(sig, L, phi_new, f, dt, P, sig_out, out)
    return phi_new


@_jit
def _pressure_residual(e, sig, phi, f, gdot, dt, p_target, P, sig_out, out):
    """p_{n+1}(e) - p_target after the step with dilation rate e; NaN if the update failed."""
    local_step(sig, phi, f, gdot, e, dt, P, sig_out, out)
    return np.nan if out[12] == FAILED else out[11] - p_target


@_jit
def pressure_step(sig, phi, f, gdot, e_guess, dt, p_target, K, P, sig_out, out):
    """Step with the dilation rate e that gives end pressure p_target; returns (e, ok).

    r(e) = p_{n+1}(e) - p_target decreases with e (dilating lowers both the trial pressure and,
    through phi_{n+1}, the critical-state pressure); it is bracketed by stepping out from the
    previous rate and solved by the Illinois variant of regula falsi. r(e) jumps where the trial
    pressure crosses zero (separation): a bracket that closes on such a jump is a failure.
    (sig_out, out) always hold the step at the returned e.
    """
    p_n = -(sig[0, 0] + sig[1, 1] + sig[2, 2]) / 3.0
    tol = 1e-13 * p_target
    e_min = (phi - 0.999) / (0.999 * dt)           # keeps phi_{n+1} below 0.999
    h = max(abs(e_guess), abs(p_n - p_target) / (K * dt), 1e-9 / dt)
    args = (sig, phi, f, gdot, dt, p_target, P, sig_out, out)
    a = e_guess
    ra = _pressure_residual(a, *args)
    if not np.isfinite(ra) or abs(ra) <= tol:
        return a, np.isfinite(ra)
    b, rb = a, ra
    for _ in range(_MAXIT):                         # bracket
        if ra > 0.0:
            b = a + h                               # dilate more: lower pressure
        else:
            b = a - h if a - h > e_min else 0.5 * (a + e_min)
        rb = _pressure_residual(b, *args)
        if not np.isfinite(rb) or (rb > 0.0) != (ra > 0.0) or abs(rb) <= tol:
            break
        a, ra = b, rb
        h *= 4.0
    if not np.isfinite(rb) or (rb > 0.0) == (ra > 0.0) or abs(rb) <= tol:
        return b, bool(np.isfinite(rb) and abs(rb) <= tol)
    side = 0
    c = b
    for _ in range(_MAXIT):                         # Illinois regula falsi
        c = b - rb * (b - a) / (rb - ra)
        if not (min(a, b) < c < max(a, b)):
            c = 0.5 * (a + b)
        rc = _pressure_residual(c, *args)
        if not np.isfinite(rc) or abs(rc) <= tol:
            return c, np.isfinite(rc)
        if abs(b - a) <= 4e-16 * max(abs(a), abs(b)):       # converged onto a jump of p(e)
            return c, abs(rc) <= PRESSURE_TOL * p_target
        if (rc > 0.0) == (rb > 0.0):
            b, rb = c, rc
            if side == -1:
                ra *= 0.5
            side = -1
        else:
            a, ra = b, rb
            b, rb = c, rc
            if side == 1:
                ra *= 0.5
            side = 1
    return c, False


@_jit
def _advance(sig, phi, f, e, gdot, h, nsub, mode, p_target, K, G, P, sig_out, out, sig_w):
    """nsub sub-steps of length h from (sig, phi, f, e) into sig_out (and out, the last step's
    fields). Returns (code, phi, f, e, q, elastic): q = max over the sub-steps of
    G h gdot_p/taubar, the part of the trial stress the plastic correction removes relative to
    what remains (the cancellation measure of the update); elastic: a sub-step ended unyielded."""
    sig_w[:, :] = sig
    q = 0.0
    elastic = False
    for _ in range(nsub):
        if mode == 0:
            phi_new = local_step(sig_w, phi, f, gdot, 0.0, h, P, sig_out, out)
            if out[12] == FAILED:
                return UPDATE_FAILED, phi, f, e, q, elastic
        else:
            e, ok = pressure_step(sig_w, phi, f, gdot, e, h, p_target, K, P, sig_out, out)
            phi_new = phi / (1.0 + e * h)
            if not ok:
                return PRESSURE_FAILED, phi, f, e, q, elastic
        if yield_residual(out) > YIELD_TOL:
            return YIELD_VIOLATED, phi, f, e, q, elastic
        finite = np.isfinite(out[0]) and np.isfinite(phi_new)
        for i in range(3):
            for j in range(3):
                finite = finite and np.isfinite(sig_out[i, j])
        if not finite:
            return NOT_FINITE, phi, f, e, q, elastic
        if out[10] > 0.0 and out[1] > 0.0:
            q = max(q, G * h * out[1] / out[10])
        elastic = elastic or out[12] == ELASTIC
        sig_w[:, :] = sig_out
        phi, f = phi_new, out[0]
    return OK, phi, f, e, q, elastic


@_jit
def _run(sig0, phi0, f0, gdot, dt, nsteps, every, mode, p_target, K, G, P, rec, n_min,
         x_elastic, max_total, stats):
    """March nsteps of dt, each as n >= n_min equal sub-steps; write every ``every``-th state
    into rec. A step whose sub-steps fail, leave the yield surface or exceed the cancellation
    bound Q_MAX, or has an unyielded sub-step longer than the strain x_elastic, is recomputed from
    its start with more sub-steps (the count adapts both ways, never below n_min). Returns
    (code, step, rows); stats = [sub-steps, max n, retries]."""
    sig = sig0.copy()
    sig_out = np.empty((3, 3))
    sig_w = np.empty((3, 3))
    out = np.zeros(NOUT)
    phi, f, e = phi0, f0, 0.0
    row = 0
    nsub = n_min
    total = 0
    for n in range(nsteps):
        while True:
            code, phi_new, f_new, e_new, q, el = _advance(sig, phi, f, e, gdot, dt / nsub, nsub,
                                                          mode, p_target, K, G, P, sig_out, out,
                                                          sig_w)
            spin_ok = not el or dt / nsub * gdot <= x_elastic * (1.0 + 1e-12)
            if code == OK and q <= Q_MAX and spin_ok:
                break
            if code == OK and not spin_ok:           # unyielded: the spin's growth bound
                grow = max(2.0, np.ceil(dt * gdot / x_elastic) / nsub)
            elif code == OK:                         # too much cancellation: shorter steps
                grow = min(max(2.0, 1.5 * q / Q_MAX), 1e6)
            else:
                grow = 2.0
            if nsub * grow > MAX_SUBSTEPS_PER_STEP or total > max_total:
                stats[0], stats[2] = total, stats[2] + 1
                return (code if code != OK else CANCELLATION), n, row
            nsub = int(np.ceil(nsub * grow))
            stats[2] += 1
        total += nsub
        stats[1] = max(stats[1], nsub)
        if total > max_total:
            stats[0] = total
            return TOO_MANY, n, row
        sig[:, :] = sig_out
        phi, f, e = phi_new, f_new, e_new
        if q < 0.25 * Q_MAX and nsub > n_min:       # room again: fewer sub-steps
            nsub = max(n_min, nsub // 2)
        if (n + 1) % every == 0 or n == nsteps - 1:
            rec[row, 0] = (n + 1) * dt
            rec[row, 1], rec[row, 2], rec[row, 3], rec[row, 4] = sig[0, 0], sig[1, 1], sig[2, 2], \
                sig[0, 1]
            rec[row, 5], rec[row, 6] = phi, e
            for k in range(NOUT):
                rec[row, _REC + k] = out[k]
            row += 1
    stats[0] = total
    return OK, nsteps, row


def point_parameters(m: Material, G=None, K=None, K0=None) -> tuple[Material, np.ndarray]:
    """The material with G, K, K0 filled in (given, the material's, or the defaults) and its
    kernel parameter vector. Defaults: G = 1e4 Pa, K = (8.3/3.8) G, K0 = 1."""
    G, K0 = skeleton(m, G, K0)
    K = float(check_positive("K [Pa]", K if K is not None else (m.K or K_OVER_G * G)))
    m = m.replace(G=G, K=K, K0=K0)
    return m, rheology.kernel_parameters(m)


def initial_point(m: Material, phi: float, *, stress0=None, f0=None, pressure0=None, label=str):
    """Initial (stress 3x3, f): the steady state at granular shear stress ``stress0`` [Pa], or
    rest under isotropic contact pressure ``pressure0`` >= 0 [Pa] (default 1e-3 tau*; 0: stress
    free) with f0 (0) in [0, 1] (:data:`rheometer.limits.STRUCTURE`, named ``label("f0")``)."""
    sig = np.zeros((3, 3))
    f = None if f0 is None else float(limits.STRUCTURE.check(label("f0"), f0))
    if stress0 is not None:
        st = rheology.steady_state_stress(float(check_positive("stress0 [Pa]", stress0)), phi, m)
        f = float(st.f) if f is None else f
        p = float(st.pressure)
        sig[0, 1] = sig[1, 0] = float(stress0)
    else:
        f = 0.0 if f is None else f
        p = float(check_nonnegative("pressure0 [Pa]", pressure0 if pressure0 is not None
                                    else 1e-3 * m.tau_star))
    sig[0, 0] = sig[1, 1] = sig[2, 2] = -p
    return sig, f


def simple_shear_point(material, phi: float, rate: float, t_end: float, dt: float, *,
                       control: str = "volume", pressure: float | None = None,
                       f0: float | None = None, stress0: float | None = None,
                       pressure0: float | None = None, G: float | None = None,
                       K: float | None = None, K0: float | None = None,
                       points: int = 400, elastic_limit: bool = False,
                       label=str) -> pd.DataFrame:
    """Drive one material point of the Table 8 law through homogeneous simple shear.

    Parameters
    ----------
    material : str or Material
    phi : float
        (Initial) volume fraction, 0 < phi < 1.
    rate : float
        Imposed shear rate gdot = L_xy [1/s]: 0 or in [1e-9, 1e9] (:data:`rheometer.limits.RATE`).
    t_end, dt : float
        Duration and largest time step [s] (output and accuracy), each in [1e-12, 1e9] s
        (:data:`rheometer.limits.DURATION`), dt <= t_end; each step is split into
        sub-steps where the rate needs it (module docstring): at most 0.01 strain per local
        update, less for an unyielded point, fewer where G h gdot_p/taubar > 1e6. Checked once,
        with the update count, by :func:`check_drive`.
    control : {"volume", "pressure"}
        Fixed phi (L_yy = 0), or imposed granular pressure ``pressure`` [Pa] (L_yy solved).
    stress0 : float, optional
        Start from the steady state at this granular shear stress [Pa] (sigma_xy = stress0,
        isotropic pressure and f of Eq. 13); otherwise from rest.
    f0 : float, optional
        Initial structure (default: steady f, or 0 from rest).
    pressure0 : float, optional
        Contact pressure at rest [Pa], >= 0 (default 1e-3 tau*, or ``pressure`` under pressure
        control; 0: stress free).
    G, K, K0 : float, optional
        Moduli [Pa] and structure rate; default the material's, else 1e4 Pa, (8.3/3.8) G, 1.
    points : int
        Approximate number of output rows, in [1, 1e7] (:data:`POINTS`).
    elastic_limit : bool
        End the run where its elastic strain taubar/G or p/K passes
        :data:`rheology.elastic.ELASTIC_STRAIN_LIMIT` (0.1): the command line always sets it; the
        default False lets tests follow the Jaumann algebra to large strains.
    label : callable
        What a refusal calls a parameter, ``label(name)`` of ``rate, t_end, dt, points, f0`` (the
        command line: its option; default the name itself).

    Returns
    -------
    DataFrame
        ``time_s, shear_rate_per_s, shear_stress_Pa`` (granular sigma_xy),
        ``granular_shear_stress_Pa`` (taubar), ``granular_pressure_Pa, normal_stress_xx_Pa,
        normal_stress_yy_Pa, normal_stress_zz_Pa, N1_Pa, N2_Pa, f, plastic_shear_rate_per_s,
        phi, dilation_rate_per_s, beta, xi2_per_s, case, iterations``.

    Raises
    ------
    ValueError
        Bad input (including a time step longer than the run, or a run needing more than 2e7
        local updates, with the valid values: :func:`check_drive`).
    rheology.run_end.EndedEarly (a RuntimeError)
        The local update or the pressure solve failed even with 1e9 sub-steps per step, or the
        state became non-finite (with the step, time and state), or (``elastic_limit``) the
        elastic strain taubar/G or p/K passed the small-strain limit 0.1 (:mod:`rheology.elastic`):
        ``partial`` holds the rows before (:mod:`rheology.run_end`; None if there are none).

    ``attrs``: ``substeps`` (local updates in all), ``max_substeps_per_step``, ``retries``.
    """
    m0 = rheology.get_material(material)
    if control not in ("volume", "pressure"):
        raise ValueError(f"control = {control!r} must be 'volume' or 'pressure'")
    volume = control == "volume"     # phi is kept: below phi_j; else it evolves, below 1
    phi = float(Param(PHI_MIN, lt(m0.phi_j if volume else 1.0, (
        f"volume-controlled shear needs phi below phi_j = {m0.phi_j}" if volume else
        "a volume fraction: the grains fill less than the whole volume"))).check("phi", phi))
    rate, t_end, dt = check_drive(rate, t_end, dt, label)
    if control == "pressure":
        if pressure is None:
            raise ValueError("pressure control needs the imposed granular pressure [Pa]")
        pressure = float(check_positive("pressure [Pa]", pressure))
        if pressure0 is None and stress0 is None:
            pressure0 = pressure
    m, P = point_parameters(m0, G, K, K0)
    sig0, f_init = initial_point(m, phi, stress0=stress0, f0=f0, pressure0=pressure0,
                                 label=label)
    nsteps = int(round(t_end / dt))
    every = max(1, nsteps // int(POINTS.check(label("points"), points)))
    n_min, x_max, x_el = substeps(rate, t_end, dt)
    def march(sig, phi, f, steps, every, rec, stats):
        return _run(sig, phi, f, rate, dt, steps, every, 0 if volume else 1, pressure or 0.0,
                    m.K, m.G, P, rec, n_min, x_el, MAX_SUBSTEPS, stats)

    rec = np.empty((nsteps // every + 2, _REC + NOUT))
    stats = np.zeros(3, dtype=np.int64)
    code, n, rows = march(sig0, phi, f_init, nsteps, every, rec, stats)
    end = None
    if code != OK:
        what = {UPDATE_FAILED: "the local update's bracketed solve failed",
                PRESSURE_FAILED: "no dilation rate gives the imposed pressure (p(e) jumps over "
                                 "it, e.g. to separation)",
                NOT_FINITE: "the state became non-finite",
                YIELD_VIOLATED: f"the local update ended off the yield surface (|f_1| > "
                                f"{YIELD_TOL:g} relative)",
                CANCELLATION: f"the plastic correction cancels more than {Q_MAX:g} times the "
                              f"remaining stress (G h gdot_p/taubar)",
                TOO_MANY: f"more than {MAX_SUBSTEPS:.0e} sub-steps were needed"}[code]
        last = rec[rows - 1] if rows else None
        state = (f"last recorded t = {last[0]:.6g} s: sigma_xy = {last[4]:.6g} Pa, "
                 f"p = {last[_OF['pressure']]:.6g} Pa, f = {last[_OF['f']]:.6g}, "
                 f"phi = {last[5]:.6g}" if last is not None else "before the first output row")
        kind = ("law_failure" if code in (UPDATE_FAILED, PRESSURE_FAILED, YIELD_VIOLATED)
                else "solver_failure")
        end = RunEnd(kind, f"material point ({control} control, phi0 = {phi:g}, rate = "
                           f"{rate:g} 1/s, dt = {dt:g} s): {what} at step {n + 1} (t = "
                           f"{(n + 1) * dt:.6g} s) even with {int(stats[1])} sub-steps per step "
                           f"({int(stats[0])} in all); {state}", past_s=(n + 1) * dt)
    df = _frame(np.vstack([_initial_row(sig0, phi, f_init, m, stress0), rec[:rows]]), rate)
    df.attrs.update(substeps=int(stats[0]), max_substeps_per_step=int(stats[1]),
                    retries=int(stats[2]), strain_per_substep_max=x_max)
    if stats[1] > 1:
        df.attrs["substeps_note"] = (
            f"sub-stepped: {int(stats[0])} local updates for {nsteps} steps of {dt:g} s (at "
            f"most {int(stats[1])} per step; strain per sub-step <= {x_max:.3g})")
    # the hypoelastic law holds for small elastic strains only: taubar/G and p/K (rheology.elastic)
    where = (f"material point ({control} control, phi0 = {phi:g}, rate = {rate:g} 1/s, "
             f"G = {m.G:g} Pa, K = {m.K:g} Pa)")
    advice = ("impose a lower rate, pressure or initial stress or a shorter time, or stiffer "
              "moduli (--G, --K)")

    def first_past(d):
        """(first row past the elastic limit, its RunEnd) of taubar/G and p/K, or None."""
        found = [past_elastic_limit(d["time_s"], d[col], mod, stress_name=s_name,
                                    modulus_name=m_name, where=where, advice=advice)
                 for col, mod, s_name, m_name in (("granular_shear_stress_Pa", m.G, "taubar", "G"),
                                                  ("granular_pressure_Pa", m.K, "p", "K"))]
        found = [c for c in found if c is not None]
        return min(found, key=lambda c: c[0]) if found else None

    keep = len(df)
    cut = first_past(df) if elastic_limit else None
    if cut is not None and cut[0] < keep:
        keep, end = cut
        if 0 < keep and every > 1:   # the output interval of the crossing, again step by step
            r = df.iloc[keep - 1]
            sig = np.diag([r["normal_stress_xx_Pa"], r["normal_stress_yy_Pa"],
                           r["normal_stress_zz_Pa"]])
            sig[0, 1] = sig[1, 0] = r["shear_stress_Pa"]
            n_fine = int(round((df["time_s"].iloc[keep] - r["time_s"]) / dt))
            rec = np.empty((n_fine + 2, _REC + NOUT))
            _, _, rows = march(sig, r["phi"], r["f"], n_fine, 1, rec, np.zeros(3, dtype=np.int64))
            rec[:rows, 0] += r["time_s"]
            fine = pd.concat([df.iloc[:keep], _frame(rec[:rows], rate)], ignore_index=True)
            cut = first_past(fine)
            if cut is not None:
                df, (keep, end) = fine, cut
    if end is not None:           # the rows before the end (rheology.run_end)
        df = df.iloc[:keep]
        end = end.replace(time_s=float(df["time_s"].iloc[-1]) if keep else None)
        df.attrs["end"] = end
        raise EndedEarly([end], partial=df if keep else None)
    return df


#: Output rows of a material point: at least the end state, at most 1e7.
POINTS = limits.rows(1, "the end state", le(10 ** 7, "1e7 rows make a CSV of about 1 GB"))


def substeps(rate: float, t_end: float, dt: float) -> tuple[int, float, float]:
    """(least sub-steps per step of dt, largest strain of a sub-step, largest strain of an
    unyielded sub-step) at shear rate ``rate`` over ``t_end`` (see :func:`simple_shear_point`;
    the inputs checked by :func:`check_drive`)."""
    strain = rate * t_end
    x_max = STRAIN_PER_SUBSTEP
    x_el = min(x_max, 2.0 * SPIN_GROWTH / strain) if strain > 0 else np.inf
    n_min = max(1, int(np.ceil(dt * rate / x_max))) if rate > 0 else 1
    return n_min, x_max, x_el


def check_drive(rate, t_end, dt, label=str) -> tuple[float, float, float]:
    """(rate [1/s], t_end [s], dt [s]) of a material point, checked once (the one check of
    :func:`simple_shear_point` and of the command line, whose options ``label(name)`` names).

    - ``rate`` in :data:`rheometer.limits.RATE` (0 or [1e-9, 1e9] 1/s), ``t_end`` and ``dt`` in
      :data:`rheometer.limits.DURATION` ([1e-12, 1e9] s), ``dt <= t_end`` (at least one step);
    - the local updates, max(1, ceil(dt rate / x)) per step (x = :data:`STRAIN_PER_SUBSTEP`,
      :func:`substeps`) times round(t_end / dt) steps, at most :data:`MAX_SUBSTEPS`. Two
      limits, each refusal naming what helps: the steps, set by t_end / dt (a longer dt or a
      shorter t_end), and the strain per update, set by rate x t_end (no dt helps: a lower rate
      or a shorter t_end).

    Raises
    ------
    ValueError
        One line naming ``label(name)``, with the valid values at the others'.
    """
    rate = float(limits.RATE.check(label("rate"), rate))
    t_end = float(limits.DURATION.check(label("t_end"), t_end))
    dt = float(limits.DURATION.check(label("dt"), dt))
    Param(physical.TIME_MIN, le(t_end, f"the step must not exceed the run, {label('t_end')} = "
                                       f"{t_end:g} s"), unit="s").check(label("dt"), dt)
    x = STRAIN_PER_SUBSTEP
    steps = t_end / dt
    per_step = max(1.0, math.ceil(dt * rate / x)) if rate > 0 else 1.0
    count = per_step * round(steps)
    if count <= MAX_SUBSTEPS:
        return rate, t_end, dt
    R, T, D = label("rate"), label("t_end"), label("dt")
    strain = rate * t_end
    if strain / x > MAX_SUBSTEPS:     # the strain alone needs too many updates: dt cannot help
        raise ValueError(
            f"{T} = {t_end:g} s at {R} = {rate:g} 1/s is a shear strain of {strain:.3g}: "
            f"{strain / x:.3g} local updates at least whatever {D} (strain per update <= {x:g}, "
            f"the explicit Jaumann spin's bound), more than the limit {MAX_SUBSTEPS:.0e}; valid: "
            f"{T} <= {MAX_SUBSTEPS * x / rate:.3g} s at this {R}, or {R} <= "
            f"{MAX_SUBSTEPS * x / t_end:.3g} 1/s at this {T}")
    dt_min = t_end / MAX_SUBSTEPS
    t_max = MAX_SUBSTEPS * dt / per_step
    valid = (f"{D} >= {dt_min:.3g} s at this {T}, or {T} <= {t_max:.3g} s at this {D}"
             if dt < dt_min else     # else: the rounding up of the updates per step
             f"{T} <= {t_max:.3g} s at this {D} and {R}, or a lower {R}")
    raise ValueError(
        f"{D} = {dt:g} s gives {count:.3g} local updates to {T} = {t_end:g} s ({steps:.3g} steps"
        + (f" of {per_step:.0f} updates at {R} = {rate:g} 1/s" if per_step > 1 else "")
        + f"), more than the limit {MAX_SUBSTEPS:.0e}; valid: {valid}")


def _initial_row(sig0, phi, f, m: Material, stress0):
    """The initial state as an output row: at rest (plastic rate 0, beta = K3 (phi - phi_m(f)),
    the dilation angle at I_m = 0) or the steady state at ``stress0`` (its critical-state rate,
    beta = 0); no plastic volume rates, no iterations."""
    row = np.zeros(_REC + NOUT)
    row[:7] = [0.0, sig0[0, 0], sig0[1, 1], sig0[2, 2], sig0[0, 1], phi, 0.0]
    taubar, p = rheology.invariants(sig0)
    row[_OF["f"]], row[_OF["taubar"]], row[_OF["pressure"]] = f, float(taubar), float(p)
    if stress0 is not None:
        row[_OF["shear_rate_p"]] = float(rheology.steady_state_stress(float(stress0), phi,
                                                                      m).shear_rate)
    else:
        row[_OF["beta"]] = m.K3 * (phi - float(rheology.phi_m(f, m)))
    row[_OF["case"]] = np.nan                       # "initial"
    return row


def _frame(rec: np.ndarray, rate: float) -> pd.DataFrame:
    sxx, syy, szz, sxy = rec[:, 1], rec[:, 2], rec[:, 3], rec[:, 4]
    case = rec[:, _OF["case"]]
    return pd.DataFrame({
        "time_s": rec[:, 0], "shear_rate_per_s": np.full(rec.shape[0], rate),
        "shear_stress_Pa": sxy, "granular_shear_stress_Pa": rec[:, _OF["taubar"]],
        "granular_pressure_Pa": rec[:, _OF["pressure"]], "normal_stress_xx_Pa": sxx,
        "normal_stress_yy_Pa": syy, "normal_stress_zz_Pa": szz, "N1_Pa": sxx - syy,
        "N2_Pa": syy - szz, "f": rec[:, _OF["f"]],
        "plastic_shear_rate_per_s": rec[:, _OF["shear_rate_p"]], "phi": rec[:, 5],
        "dilation_rate_per_s": rec[:, 6], "beta": rec[:, _OF["beta"]],
        "xi2_per_s": rec[:, _OF["xi2"]],
        "case": [CASE_NAMES.get(int(c), "initial") if np.isfinite(c) else "initial"
                 for c in case],
        "iterations": rec[:, _OF["iterations"]]})
