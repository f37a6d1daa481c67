"""Oscillatory shear of the 0-D model: imposed strain gamma0 sin(omega t) or mixture stress
sigma0 sin(omega t), run to the periodic steady state on SUNDIALS IDA, analysed by harmonics.

The model is the reduced 0-D law of :mod:`rheometer.model` (paper Eqs. 35-37, the Table 8
structure law) with the mixture stress ``sigma = taubar + eta_F gdot``, ``eta_F = eta0 (1 + 5/2
phi)``. The shear rate is imposed (strain control, ``gdot = gamma0 omega cos(omega t)``) or
follows from the imposed stress (``gdot = (sigma(t) - taubar)/eta_F``); ``y = [taubar, gap,
strain]`` obey::

    taubar' = G (gdot - sign(taubar) gdot_cs(|taubar|, gap))       Eq. (36) with the imposed drive
    gap'    = -(phi_j - phi_c) df/dt(f, |taubar|, |gdot_p|)         Table 8 structure law
    strain' = gdot

solved by IDA (residual ``yp - rhs``, exact Jacobian by complex-step partials), as a program
step ``oscillate at F Hz with strain A for N cycles`` does.

Linear viscoelasticity (the small-amplitude limit). From rest (``taubar = 0``, ``f = 0``) f grows
only at order ``|taubar/tau*|^(3/2)`` and the grain-inertia term of
:func:`rheology.laws.critical_shear_rate` is second order, so to first order
``gdot_p = taubar/eta_g``, ``eta_g = eta0 [2 mu* (a0 phi/(phi_j - phi))^2 + 5/2 phi^2/(phi_j -
phi)]`` (the low-stress plateau of Eq. 24), and ``taubar' = G (gdot - taubar/eta_g)``: a Maxwell
element of modulus G and relaxation time ``lambda = eta_g/G`` in parallel with the Newtonian
fluid ``eta_F``. With ``gamma = Re[gamma* e^(i omega t)]``, ``sigma = Re[G* gamma* e^(i omega t)]``::

    G*(omega) = G i omega lambda/(1 + i omega lambda) + i omega eta_F
    G'  = G (omega lambda)^2/(1 + (omega lambda)^2)
    G'' = G omega lambda/(1 + (omega lambda)^2) + omega eta0 (1 + 5/2 phi)

At low frequency: the Newtonian plateau of Eq. (24); at high, ``G' -> G`` and the fluid
dominates the loss once ``omega >> G/sqrt(eta_g eta_F)``.

Analysis of a cycle (``N`` samples at uniform phase, period ``T = 2 pi/omega``): the harmonic
``c_n = (2/N) sum_k s_k e^(-i n omega t_k)`` of a signal s; with ``gamma = gamma0 sin(omega t)``,
``G* = G' + i G'' = c_sigma,1/c_gamma,1`` (under stress control with the strain's harmonic, its
linear drift over the cycle removed first); ``I3/I1 = |c_3|/|c_1|`` of the response.
``|eta*| = |G*|/omega``. Lissajous-Bowditch projections: stress against strain and rate;
Ewoldt's elastic and viscous stresses ``(sigma(t) -+ sigma(-t))/2`` (strain control).

Periodic steady state: cycles are run until the cycle-to-cycle change of ``c_1``, ``c_3`` and the
mean stress (strain control) or the strain's drift over a cycle (stress control), relative to
``|c_1|``, and of the cycle-mean structure f (absolute), is below ``tol`` and so is its geometric
projection ``change r/(1 - r)`` (``r`` the ratio of the last two changes). The cycles used are
reported; a point not converged within ``max_cycles`` has ``converged = False``.

Acceleration: where the change shrinks by less than a factor 2 per cycle, the state jumps (Aitken
extrapolation along one slow mode, else a damped Newton step on the cycle map x -> Phi(x), the
state one period later); the test then starts afresh, so the reported cycle is always an
integrated one repeating itself to ``tol`` (column ``extrapolations``).

Where the paper is silent: G and K0 default to the material's, else G = 1e4 Pa and K0 = 1. Each
point starts from rest (f = 0) carrying the periodic stress of the linearised model (taubar(0) =
Re[G_M* c_drive], G_M* the Maxwell part; under stress control also the strain's linear phase)
so that the Maxwell transient need not be waited out; or, with ``start="previous"``, from the
final state of the previous point (as an instrument runs a sweep).
"""

from __future__ import annotations

import time

import numpy as np
import pandas as pd

from scipy.optimize import minimize_scalar

import rheology
from rheology import laws
from rheology.run_end import RunEnd
from rheology.steady import steady_fold
from runkit.ida import IDAFailed, Solver, captured
from runkit.limits import ge, le
from runkit.params import Param, check_positive

from . import limits, model
from .harmonics import cycle_harmonics, elastic_viscous, harmonics  # noqa: F401
from .limits import check_peak_rate
from .transient import Maxwell, check_phi, drive, skeleton

#: Drive modes.
STRAIN, STRESS = 0, 1
#: Defaults.
DEFAULT_SAMPLES = 128
DEFAULT_TOL = 1e-5
DEFAULT_MAX_CYCLES = 300
DEFAULT_RTOL = 1e-7
_GAP_SCALE = 1e-8
#: Newton steps on the cycle map per point, at most.
MAX_NEWTON = 12

#: Columns of the per-point table (units in the names).
POINT_COLUMNS = ("phi", "control", "frequency_Hz", "angular_frequency_rad_per_s",
                 "strain_amplitude", "stress_amplitude_Pa", "peak_stress_Pa",
                 "storage_modulus_Pa", "loss_modulus_Pa", "complex_viscosity_Pa_s", "tan_delta",
                 "I3_over_I1", "linear_storage_modulus_Pa", "linear_loss_modulus_Pa",
                 "mean_f", "max_f", "max_elastic_strain", "cycles", "extrapolations",
                 "cycle_change", "converged", "reason", "not_periodic_why")
#: Columns of a point that failed (IDA, or an unphysical state) left empty (null) in its row;
#: ``reason`` holds the solver's diagnostics (empty for the points that ran);
#: ``not_periodic_why`` says which test of the periodic state a point that ran failed (empty
#: when periodic).
FAILED_EMPTY = ("strain_amplitude", "stress_amplitude_Pa", "peak_stress_Pa",
                "storage_modulus_Pa", "loss_modulus_Pa", "complex_viscosity_Pa_s", "tan_delta",
                "I3_over_I1", "mean_f", "max_f", "max_elastic_strain", "cycles",
                "extrapolations", "cycle_change")
#: Columns of the waveform table (the last, periodic cycle of every point).
WAVE_COLUMNS = ("point", "phi", "frequency_Hz", "strain_amplitude", "stress_amplitude_Pa",
                "phase_rad", "time_s", "strain", "shear_rate_per_s", "shear_stress_Pa",
                "granular_shear_stress_Pa", "f", "elastic_stress_Pa", "viscous_stress_Pa")


# ------------------------------------------------------------------ the linear limit
def _moduli(material, phi, G, K0):
    m = rheology.get_material(material)
    return (m, check_phi("phi", phi, m), *skeleton(m, G, K0))


def maxwell(material, phi: float, G: float | None = None) -> Maxwell:
    """The linearised (small-amplitude) model at rest of ``material`` at ``phi`` (see module doc).

    ``G`` [Pa] defaults to the material's, else 1e4 Pa. Raises ValueError for phi outside
    (0, phi_j) or G <= 0.
    """
    m, phi, G, _ = _moduli(material, phi, G, None)
    eta_g = m.eta0 * float(rheology.granular_viscosity(phi, 0.0, m))
    return Maxwell(G, eta_g, float(laws.fluid_viscosity(phi, m.eta0)))


def linear_modulus(material, phi: float, frequency, G: float | None = None) -> np.ndarray:
    """Small-amplitude complex modulus G* = G' + i G'' [Pa] at ``frequency`` [Hz] (any shape)."""
    f = check_positive("frequency [Hz]", frequency)
    return maxwell(material, phi, G).modulus(2.0 * np.pi * f)


def dst_onset_stress(material, phi: float) -> float:
    """Mixture shear stress [Pa] at the onset of DST: the first fold of the steady curve, where
    the shear rate stops increasing with the stress (a maximum of gdot(taubar); Eq. 13 with
    Eq. 1). Raises ValueError if the steady curve of ``phi`` has no fold (no DST)."""
    m = rheology.get_material(material)
    fold = steady_fold(m, phi)
    if fold is None:
        raise ValueError(f"phi = {phi:g}: the steady curve of {m.name} has no fold (no DST)")
    taus, _, _, i = fold
    res = minimize_scalar(lambda x: -float(rheology.steady_state_stress(np.exp(x), phi,
                                                                         m).shear_rate),
                          bounds=(np.log(taus[i - 1]), np.log(taus[i + 1])), method="bounded",
                          options=dict(xatol=1e-10))
    return float(rheology.steady_state_stress(np.exp(res.x), phi, m).shear_stress)


# ------------------------------------------------------------------ one point
def _not_periodic_why(changes, tol: float) -> str:
    """Which test of the periodic steady state fails ("": none): the last cycle-to-cycle change
    d and its geometric projection ``d r/(1 - r)`` (r the ratio of the last two) below ``tol``."""
    if len(changes) < 2:
        return f"fewer than two cycle-to-cycle changes ({len(changes)})"
    d, d0 = changes[-1], changes[-2]
    r = d / d0 if d0 > 0 else 0.0
    projected = d * r / (1.0 - r) if r < 1.0 else float("inf")
    if d < tol and projected < tol:
        return ""
    return (f"change d = {d:.2g}, projected change d r/(1-r) = {projected:.2g} (r = {r:.2g}); "
            f"both must be < tol = {tol:g}")


def _extrapolate(starts, r_min: float = 0.3, r_max: float = 0.99, cos_min: float = 0.99):
    """Aitken extrapolation along one slow mode of the cycle map, or None.

    ``starts`` are the scaled states (taubar/taubar_scale, f units) at the starts of the last
    three cycles. Near the periodic state x*, the differences d_k = x_(k+1) - x_k of a single
    slow mode are parallel and shrink by a ratio r per cycle, so x* = x_last + d_last r/(1 - r).
    Applied only when the last two differences are parallel (cosine > ``cos_min``) and
    r_min < r < r_max (else two modes are slow: a Newton step is taken instead)."""
    x = np.asarray(starts[-3:], dtype=float)
    d0, d1 = x[1] - x[0], x[2] - x[1]
    n0, n1 = float(np.dot(d0, d0)), float(np.dot(d1, d1))
    if n0 <= 0.0 or n1 <= 0.0:
        return None
    cos = float(np.dot(d0, d1)) / np.sqrt(n0 * n1)
    r = float(np.dot(d0, d1)) / n0
    if cos < cos_min or not (r_min < r < r_max):
        return None
    return x[2] + d1 * (r / (1.0 - r))


def _newton_step(x, fx, jac_cols, lo, hi):
    """One Newton step on the cycle map x -> Phi(x) (periodic state: Phi(x) = x).

    ``fx = Phi(x)``; ``jac_cols`` the finite-difference columns of d Phi/d x. Returns the new
    state, components clipped to [lo, hi], or None if I - J is singular."""
    J = np.column_stack(jac_cols)
    A = J - np.eye(x.size)
    if not np.all(np.isfinite(A)) or abs(np.linalg.det(A)) < 1e-14 * max(1.0, np.abs(A).max()) ** 2:
        return None
    new = x - np.linalg.solve(A, fx - x)
    return np.minimum(np.maximum(new, lo), hi)


def oscillate(material, phi: float, frequency: float, amplitude: float, *,
              control: str = "strain", G: float | None = None, K0: float | None = None,
              max_cycles: int = DEFAULT_MAX_CYCLES, min_cycles: int = 2, tol: float = DEFAULT_TOL,
              samples: int = DEFAULT_SAMPLES, rtol: float = DEFAULT_RTOL, state=None,
              fixed_cycles: bool = False, extrapolate: bool = True, label=str):
    """One oscillatory test run to the periodic steady state.

    Parameters
    ----------
    material : str or Material
    phi : float
        Volume fraction, 0 < phi < phi_j.
    frequency : float
        Frequency [Hz] (omega = 2 pi frequency).
    amplitude : float
        Strain amplitude gamma0 [-] (``control="strain"``) or mixture-stress amplitude sigma0 [Pa]
        (``control="stress"``), > 0.
    control : {"strain", "stress"}
    G, K0 : float, optional
        Granular shear modulus [Pa] and structure-rate scale [-] (material's, else 1e4 Pa, 1).
    max_cycles, min_cycles : int
        Cycle limits (1 <= min_cycles <= max_cycles <= 10^5).
    tol : float
        Periodic-steady-state tolerance on the cycle-to-cycle change (module docstring).
    samples : int
        Samples per cycle (16 .. 8192; the harmonics are exact for signals band-limited below
        samples/2).
    rtol : float
        IDA relative tolerance (1e-12 .. 1e-3).
    state : (taubar [Pa], gap [-], strain [-]) or None
        Initial state (default: rest, f = 0).
    fixed_cycles : bool
        Run exactly ``max_cycles`` cycles (a program step "for N cycles"); still reports the
        last change.
    extrapolate : bool
        Accelerate a slow approach to the periodic state by Newton steps on the cycle map
        (module docstring); the reported cycle is always an integrated one, compared with the
        integrated cycle before it.
    label : callable
        What a refusal calls a parameter, ``label(name)`` (the command line: its option).

    Returns
    -------
    (dict, DataFrame, tuple)
        The point (keys of :data:`POINT_COLUMNS`), the last cycle's waveform (N rows) and the
        final state (taubar, gap, strain) for a continuing sweep.

    Raises
    ------
    ValueError
        Bad input (naming the parameter and its range).
    RuntimeError
        IDA failed or returned an unphysical state (with time, state and solver counters).
    """
    m, phi, G, K0, run = _checked(material, phi, [frequency], [amplitude], control, label,
                                  dict(G=G, K0=K0, max_cycles=max_cycles, min_cycles=min_cycles,
                                       tol=tol, samples=samples, rtol=rtol))
    return _point(m, phi, G, K0, float(frequency), float(amplitude), control, state=state,
                  fixed_cycles=fixed_cycles, extrapolate=extrapolate, **run)


def _checked(material, phi, freqs, amps, control, label, options) -> tuple:
    """(material, phi, G, K0, the solver's options) with every input checked once: the
    frequencies and amplitudes (:mod:`rheometer.limits`, the peak rate of the largest), named
    by ``label(name)``; ValueError."""
    m, phi, G, K0 = _moduli(material, phi, options.get("G"), options.get("K0"))
    if control not in ("strain", "stress"):
        raise ValueError(f"control = {control!r} must be 'strain' or 'stress'")
    for f in freqs:
        limits.FREQUENCY.check(label("frequency"), f)
    for a in amps:
        limits.AMPLITUDE[control].check(label(f"{control} amplitude"), a)
    if control == "strain":
        check_peak_rate(max(freqs), max(amps))
    run = dict(max_cycles=DEFAULT_MAX_CYCLES, min_cycles=2, tol=DEFAULT_TOL,
               samples=DEFAULT_SAMPLES, rtol=DEFAULT_RTOL)
    unknown = set(options) - {"G", "K0", *run}
    if unknown:
        raise TypeError(f"unknown options {sorted(unknown)}")
    run.update({k: v for k, v in options.items() if k in run})
    for k, p in _RUN.items():
        run[k] = p.check(label(k), run[k])
    Param(ge(1, "a periodic state compares cycles"), le(run["max_cycles"], (
        f"at most max_cycles = {run['max_cycles']}")), kind="integer").check(
        label("min_cycles"), run["min_cycles"])
    return m, phi, G, K0, run


#: the solver's options of a point and their valid values
_RUN = {"max_cycles": limits.MAX_CYCLES, "tol": limits.TOL, "samples": limits.SAMPLES,
        "rtol": limits.OSCILLATION_RTOL}


def _point(m, phi, G, K0, freq, amp, control, *, max_cycles, min_cycles, tol, samples, rtol,
           state, fixed_cycles, extrapolate):
    """One point of :func:`oscillate`, its inputs checked."""
    P = model.parameters(m, phi, G, K0)
    lin = maxwell(m, phi, G)
    omega = 2.0 * np.pi * freq
    period = 1.0 / freq
    Glin = complex(lin.modulus(omega))
    mode = STRAIN if control == "strain" else STRESS
    O = drive(control, amp, omega)
    tau_scale = abs(Glin) * amp if mode == STRAIN else amp
    strain_scale = amp if mode == STRAIN else amp / abs(Glin)
    atol = 1e-3 * rtol * np.array([max(tau_scale, 1e-12 * m.tau_star), _GAP_SCALE, strain_scale])

    if state is None:      # rest (f = 0) carrying the linear periodic stress (no Maxwell transient)
        GM = Glin - 1j * omega * lin.eta_F
        c_drive = -1j * amp                          # sin(omega t) = Re[-i e^(i omega t)]
        y0 = np.array([(GM * c_drive).real, m.phi_j - phi, 0.0] if mode == STRAIN else
                      [(GM / Glin * c_drive).real, m.phi_j - phi, (c_drive / Glin).real])
    else:
        y0 = np.array(state, dtype=float)

    def rates(t, y):
        yp = np.empty(3)
        model.ode_rhs(t, y, yp, P, O)
        return yp

    def ida(tol):                        # the ODE on IDA at relative tolerance tol
        return Solver(lambda t, y, yp, res: model.ode_residual(t, y, yp, res, P, O), rtol=tol,
                      atol=atol * (tol / rtol), max_step=period / 16, max_num_steps=100_000,
                      jacfn=lambda t, y, yp, res, cj, JJ: model.ode_residual_jacobian(
                          t, y, yp, cj, JJ, P, O))

    solver = ida(rtol)
    solver.start(0.0, y0, rates(0.0, y0))
    f_m = float(laws.f_max(phi, m.phi_c, m.phi_j, m.Delta))
    f_hi = max(f_m, float(model.structure_of_gap(y0[1], P)))
    phase = 2.0 * np.pi * np.arange(samples) / samples
    prev = None
    changes: list[float] = []
    t0 = time.perf_counter()
    Y = np.empty((samples + 1, 3))
    nfev = 0
    # Newton shooting on the cycle map in scaled variables (taubar/tau_scale, f)
    weights = np.array([max(tau_scale, 1e-300), m.phi_j - m.phi_c])
    lo = np.array([-np.inf, float(model.gap_of_structure(f_hi, P))])
    hi = np.array([np.inf, float(m.phi_j - phi)])
    jumps = reverted = 0
    accelerate, backup, weak = bool(extrapolate), None, 0
    starts = [y0[:2] / weights]           # scaled cycle-start states since the last jump
    rtol_fd = max(1e-2 * rtol, 1e-12)        # the finite differences need tighter solves

    def restart(y_new):
        """Continue from ``y_new`` at the cycle's end; the periodicity test starts afresh."""
        solver.start(times[-1], y_new, rates(times[-1], y_new))
        Y[-1] = y_new
        return None, [], [y_new[:2] / weights]

    def cycle_map(t_start, x):
        """State (taubar, gap) one period after (t_start, x): a separate IDA solve."""
        y = np.array([x[0], x[1], 0.0])
        try:
            sol, _ = ida(rtol_fd).solve(np.array([t_start, t_start + period]), y,
                                        rates(t_start, y))
        except IDAFailed:
            return np.full(2, np.nan)
        return np.asarray(sol.y)[-1, :2]
    for cycle in range(1, max_cycles + 1):
        times = (cycle - 1 + np.arange(samples + 1) / samples) * period
        Y[0] = y0 if cycle == 1 else Y[-1]
        with captured() as printed:      # per cycle: per step would cost a third more time
            for k in range(1, samples + 1):
                sol = solver.ida.step(times[k], tstop=times[-1])
                if not sol.success:
                    break
                Y[k] = np.asarray(sol.y).ravel()
                nfev = int(getattr(sol, "nfev", nfev) or nfev)
        if not sol.success:
            said = f" [SUNDIALS: {printed.text.lstrip('[')[:300]}]" if printed.text else ""
            raise RuntimeError(
                f"IDA failed in oscillation at phi = {phi:g}, {freq:g} Hz, {control} "
                f"amplitude {amp:g}, cycle {cycle}, t = {float(sol.t):.6g} s: {sol.message} "
                f"(taubar = {Y[k - 1, 0]:.6g} Pa, G = {G:g} Pa, K0 = {K0:g}, rtol = {rtol:g})"
                f"{said}")
        f = model.structure_of_gap(Y[:, 1], P)
        bad = (~np.all(np.isfinite(Y), axis=1) | (f < -1e-6) | (f > f_hi + 1e-6))
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise RuntimeError(
                f"unphysical state in oscillation at phi = {phi:g}, {freq:g} Hz, amplitude "
                f"{amp:g}, cycle {cycle}, t = {times[i]:.6g} s: taubar = {Y[i, 0]:.6g} Pa, "
                f"f = {f[i]:.6g} (valid [0, {f_hi:.6g}]): tighten rtol (now {rtol:g})")
        taubar = Y[:samples, 0]
        gdot = np.array([model.shear_rate(t, tb, P, O)[0]
                         for t, tb in zip(times[:samples], taubar)])
        sigma = taubar + P[model.ETA_FLUID] * gdot
        c_sigma, c_gamma, c = cycle_harmonics(control, amp, sigma, Y[:, 2])
        mean = np.mean(sigma) if mode == STRAIN else Y[samples, 2] - Y[0, 2]
        scale = abs(c[0])
        c = np.concatenate([c, [mean]])
        f_mean = float(np.mean(model.structure_of_gap(Y[:samples, 1], P)))
        if prev is not None and scale > 0:
            changes.append(max(float(np.max(np.abs(c - prev[0]))) / scale, abs(f_mean - prev[1])))
        prev = (c, f_mean)
        converged = not _not_periodic_why(changes, tol)
        if converged and not fixed_cycles and cycle >= min_cycles:
            break
        if backup is not None and len(changes) >= 2 and cycle < max_cycles - 2:
            weak = weak + 1 if changes[-1] > 0.5 * backup[1] else 0
            if weak >= 3:                      # three jumps in a row that did not halve it
                accelerate = False
            if changes[-1] > 10.0 * backup[1]:  # the jump made it much worse: undo it, stop
                prev, changes, starts = restart(backup[0])
                accelerate = False
                reverted += 1
            backup = None
        starts.append(Y[-1, :2] / weights)
        slow = len(changes) >= 2 and changes[-2] > 0 and changes[-1] > 0.5 * changes[-2]
        if (accelerate and not fixed_cycles and slow and cycle < max_cycles - 3
                and jumps < MAX_NEWTON):
            x = Y[-1, :2] / weights
            new = (_extrapolate(starts) if len(starts) >= 3 else None)
            if new is not None:
                new = np.minimum(np.maximum(new, lo / weights), hi / weights)
            else:
                fx = cycle_map(times[-1], x * weights) / weights
                cols = []
                for i in range(2):
                    h = np.zeros(2)
                    h[i] = 1e-3 if x[i] + 1e-3 <= hi[i] / weights[i] else -1e-3
                    cols.append((cycle_map(times[-1], (x + h) * weights) / weights - fx) / h[i])
                new = _newton_step(x, fx, cols, lo / weights, hi / weights)
            if new is not None:
                # damped: taubar moves by at most the cycle's stress range, f by at most 0.2
                bound = np.array([np.ptp(Y[:, 0]) / weights[0], 0.2])
                step = new - x
                over = float(np.max(np.abs(step) / np.maximum(bound, 1e-300)))
                new = x + step / max(1.0, over)
                backup = (Y[-1].copy(), changes[-1])
                prev, changes, starts = restart(
                    np.array([new[0] * weights[0], new[1] * weights[1], Y[-1, 2]]))
                jumps += 1
    i3 = abs(c[1]) / abs(c[0])
    Gs = c_sigma / c_gamma
    f_cycle = np.clip(f[:samples], 0.0, 1.0)
    point = dict(phi=phi, control=control, frequency_Hz=freq, angular_frequency_rad_per_s=omega,
                 strain_amplitude=abs(c_gamma), stress_amplitude_Pa=abs(c_sigma),
                 peak_stress_Pa=float(np.max(np.abs(sigma))), storage_modulus_Pa=Gs.real,
                 loss_modulus_Pa=Gs.imag, complex_viscosity_Pa_s=abs(Gs) / omega,
                 tan_delta=Gs.imag / Gs.real if Gs.real > 0 else np.nan, I3_over_I1=i3,
                 linear_storage_modulus_Pa=Glin.real, linear_loss_modulus_Pa=Glin.imag,
                 mean_f=float(np.mean(f_cycle)), max_f=float(np.max(f_cycle)),
                 # elastic strain taubar/G of the skeleton over the cycle: past
                 # rheology.elastic.ELASTIC_STRAIN_LIMIT (0.1) the hypoelastic law is used
                 # outside its range (a jammed sample answering elastically to gamma0 ~ 1)
                 max_elastic_strain=float(np.max(np.abs(taubar))) / G, cycles=cycle,
                 cycle_change=changes[-1] if changes else np.nan, converged=converged,
                 extrapolations=jumps, reason="",
                 not_periodic_why="" if converged else _not_periodic_why(changes, tol),
                 seconds=time.perf_counter() - t0)
    if mode == STRAIN:
        el, vi = elastic_viscous(sigma)
    else:
        el = vi = np.full(samples, np.nan)
    wave = pd.DataFrame({
        "phase_rad": phase, "time_s": times[:samples],
        "strain": amp * np.sin(phase) if mode == STRAIN else Y[:samples, 2],
        "shear_rate_per_s": gdot, "shear_stress_Pa": sigma,
        "granular_shear_stress_Pa": taubar, "f": f_cycle, "elastic_stress_Pa": el,
        "viscous_stress_Pa": vi})
    end = (float(Y[-1, 0]), float(Y[-1, 1]), float(Y[-1, 2]))
    return point, wave, end


# ------------------------------------------------------------------ sweeps
def oscillation_sweep(material, phi, *, frequency=1.0, amplitude=0.01, control: str = "strain",
                      start: str = "rest", label=str, **options) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Amplitude and/or frequency sweep: every (phi, frequency, amplitude) combination, in the
    order given (phi outermost, then frequency, then amplitude).

    Parameters
    ----------
    material : str or Material
    phi : float or sequence of float
    frequency : float or sequence of float
        Frequencies [Hz].
    amplitude : float or sequence of float
        Strain amplitudes [-] (``control="strain"``) or mixture-stress amplitudes [Pa].
    control : {"strain", "stress"}
    start : {"rest", "previous"}
        Each point from rest, or from the final state of the previous point at the same phi.
    **options
        As for :func:`oscillate` (G, K0, max_cycles, min_cycles, tol, samples, rtol; ``label``
        names them in a refusal).

    Returns
    -------
    (points, waveforms) : DataFrames with :data:`POINT_COLUMNS` and :data:`WAVE_COLUMNS`;
    ``points.attrs`` holds the material, G, K0, the tolerance, the run time, the number of
    points that did not converge and ``ends``: one :class:`rheology.run_end.RunEnd` (kind
    ``solver_failure``, ``run`` naming the point) per point whose solve failed. Such a point
    keeps its row, with its drive (phi, control, frequency, the imposed amplitude), empty
    (NaN) results (:data:`FAILED_EMPTY`), ``converged`` False and the solver's diagnostics in
    ``reason``; it has no waveform rows; the sweep goes on (under ``start="previous"`` the
    next point starts from rest). Bad input raises ValueError before any point runs.
    """
    m = rheology.get_material(material)
    if start not in ("rest", "previous"):
        raise ValueError(f"start = {start!r} must be 'rest' or 'previous'")
    phis = np.atleast_1d(np.asarray(phi, dtype=float)).ravel()
    freqs = np.atleast_1d(np.asarray(frequency, dtype=float)).ravel()
    amps = np.atleast_1d(np.asarray(amplitude, dtype=float)).ravel()
    for name, v in (("phi", phis), ("frequency", freqs), ("amplitude", amps)):
        if v.size == 0:
            raise ValueError(f"give at least one {name}")
    # every input checked once, before any point
    _, _, G, K0, solver = _checked(m, phis[0], list(freqs), list(amps), control, label,
                                   options)
    for ph in phis[1:]:
        check_phi("phi", ph, m)
    rows, waves, ends = [], [], []
    t0 = time.perf_counter()
    for ph in phis:
        state = None
        for fr in freqs:
            for a in amps:
                try:
                    point, wave, end = _point(m, float(ph), G, K0, float(fr), float(a),
                                              control, state=state, fixed_cycles=False,
                                              extrapolate=True, **solver)
                except RuntimeError as exc:          # this point failed: its own row, no wave
                    what = "strain" if control == "strain" else "stress"
                    run = f"phi = {ph:g}, {fr:g} Hz, {what} amplitude {a:g}"
                    ends.append(RunEnd("solver_failure", str(exc), run=run))
                    lin = complex(maxwell(m, ph, G).modulus(2.0 * np.pi * fr))
                    rows.append(_failed_point(ph, control, fr, a, lin, str(exc)))
                    state = None
                    continue
                state = end if start == "previous" else None
                waves.append(wave.assign(point=len(rows), phi=ph, frequency_Hz=fr, **{
                    k: point[k] for k in ("strain_amplitude", "stress_amplitude_Pa")}))
                rows.append(point)
    points = pd.DataFrame(rows)
    seconds = points.pop("seconds")
    points = points[list(POINT_COLUMNS)]
    for c in ("cycles", "extrapolations"):                 # integers, empty where failed
        points[c] = points[c].astype("Int64")
    waveforms = (pd.concat(waves, ignore_index=True) if waves
                 else pd.DataFrame(columns=WAVE_COLUMNS))[list(WAVE_COLUMNS)]
    points.attrs.update(material=m.name, control=control, G_Pa=G, K0=K0,
                        tol=solver["tol"], seconds=time.perf_counter() - t0,
                        point_seconds=list(seconds), not_converged=int((~points["converged"]).sum()),
                        start=start, ends=ends)
    waveforms.attrs.update(points.attrs)
    return points, waveforms


def _failed_point(phi, control, frequency, amplitude, linear, reason) -> dict:
    """The row of a point whose solve failed: its drive, the linear G* (``linear``, complex
    [Pa]), NaN results, the reason."""
    nan = float("nan")
    row = {k: nan for k in POINT_COLUMNS}
    row.update(phi=phi, control=control, frequency_Hz=frequency,
               angular_frequency_rad_per_s=2.0 * np.pi * frequency, converged=False,
               linear_storage_modulus_Pa=linear.real, linear_loss_modulus_Pa=linear.imag,
               reason=reason, not_periodic_why="", seconds=nan)
    row["strain_amplitude" if control == "strain" else "stress_amplitude_Pa"] = amplitude
    return row
