"""G and K0 from stress relaxation after cessation of steady shear (Supplement, Eqs. 35-37).

Model. After steady shear at granular shear stress taubar0 (its structure f0 from Eq. 13) the
flow stops, D = W = 0: dtaubar/dt = -G gdot_p (Eq. 36) with gdot_p of Eq. (35) at the current
structure f, which follows Table 8 at the rate scale K0; taubar(t) and f(t) are the integrals of
Eq. (37). The model curve is :func:`rheometer.protocols.relax` (the 0-D model on SUNDIALS IDA that
``rheometer relax`` runs) over the data's span, interpolated to the data's times by cubic Hermite
interpolation of ln taubar with its exact slope -G gdot_p / taubar (:data:`POINTS` output times:
~1e-6 in ln taubar). With gdot = 0 the measured (mixture) stress is taubar. The steady parameters
(phi_c, phi_j, a0, a_inf, tau*, eta_B, eta0, mu_c) come from a steady fit and are held.

Fit. G and K0, shared by every curve (curves at several taubar0 or phi are fitted jointly), and
each curve's cessation time t0 on its own clock (the model is taubar(t - t0), taubar0 before
t0) unless held, by least squares on ln stress (:func:`scipy.optimize.least_squares`, trf, box
bounds :data:`G_RANGE`, :data:`K0_RANGE`, t0 within the record's first time minus its span and
plus half its span); the Jacobian in ln G, ln K0 by central differences, in t0 exactly (the
model's slope). Start: G from the record's decay time (the frozen-structure time eta_g/G with
eta_g = taubar0/gdot0 of the steady state), the best of K0 in 0.01..100 and G in 0.3..3 times that,
t0 where that start's model passes the first reading.

Intervals and flags as :mod:`rheology.fit` (:func:`rheology.fit.interval_statistics`,
Student-t; ln G and ln K0 the reporting coordinates): ``at_bound`` (K0 at its floor is the law's
limit K0 = 0, a frozen structure; any other bound is a problem), ``unidentifiable`` (interval
wider than a factor 2 for G and K0, unbounded or undefined (null), |r| > 0.99 between G and
K0; the offsets t0 trade with G by the model's form and their marginal intervals carry it),
``converged``. The reason is named where the data cause it: a curve that ends before it decays
(its last stress above taubar0/e), a structure that barely changes (K0 acts only through f).
A residual sd above :data:`MISFIT_LOG10` is a problem of its own (the model does not describe
the data: a wrong taubar0, phi or steady material).
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicHermiteSpline
from scipy.linalg import block_diag
from scipy.optimize import least_squares

import rheology
from rheology.elastic import ELASTIC_STRAIN_LIMIT
from rheology.fit import (CORR_FLAG, ParameterEstimate, central_jacobian, interval_statistics,
                          judged_estimate)
from rheology.materials import Material
from runkit.params import check_range

from .limits import K0_MAX, STRESS_MAX
from .material_point import K_OVER_G
from .protocols import relax
from .transient import check_phi

#: Search bounds of G [Pa] and K0 [-].
G_RANGE = (1e-2, STRESS_MAX)
K0_RANGE = (1e-6, K0_MAX)
#: Output times of each model run.
POINTS = 1000
#: Reporting coordinate of each parameter (t0_i: "lin").
SCALE = {"G": "log", "K0": "log"}
#: Residual sd [log10 stress] beyond which the fit does not describe the data (a factor 2 rms;
#: a rheometer's noise is a few percent, 0.01-0.02).
MISFIT_LOG10 = 0.3


@dataclass
class RelaxationCurve:
    """One measured relaxation: times [s] on the curve's own clock, stress [Pa] (kept points),
    the volume fraction and the steady granular stress taubar0 [Pa] before cessation."""

    label: str
    time: np.ndarray
    stress: np.ndarray
    phi: float
    stress0: float


@dataclass
class RelaxationFit:
    """What :func:`fit_relaxation` returns.

    material : the input material with G, K0 (and K, see :func:`fit_relaxation`) set
    parameters : G, K0, then t0_1, t0_2, ... (one per curve), as :class:`ParameterEstimate`
    model_stress, residual_log10 : per curve, at the data's times (log10 measured/model)
    t0 : cessation time per curve [s] on its clock
    delta_f : change of the structure f over each curve's record (model)
    sigma_log10 : residual standard deviation in log10 stress
    converged, problems, messages : as :class:`rheology.fit.FitResult`
    n_runs : model runs (IDA solves of relax), seconds : wall time
    """

    material: Material
    parameters: list[ParameterEstimate]
    curves: list[RelaxationCurve]
    model_stress: list[np.ndarray]
    residual_log10: list[np.ndarray]
    t0: np.ndarray
    delta_f: np.ndarray
    sigma_log10: float
    converged: bool
    confidence: float
    correlation: tuple[list[str], np.ndarray]
    problems: list[str] = field(default_factory=list)
    messages: list[str] = field(default_factory=list)
    n_runs: int = 0
    seconds: float = 0.0

    def parameter(self, name: str) -> ParameterEstimate:
        return next(p for p in self.parameters if p.name == name)


def model_log_stress(m: Material, phi: float, stress0: float, G: float, K0: float,
                     t_after: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """ln taubar and d ln taubar/dt at times ``t_after`` after cessation (taubar0 before it),
    and the change of f over the run: :func:`rheometer.protocols.relax` interpolated (module
    docstring). Past the last time the solver resolves (taubar < 1e-12 taubar0) ln taubar goes on
    at its last slope."""
    t_after = np.asarray(t_after, float)
    ln = np.full(t_after.shape, np.log(stress0))
    slope = np.zeros(t_after.shape)
    after = t_after > 0
    if not after.any():
        return ln, slope, 0.0
    df = relax(m, phi, stress0, float(t_after.max()), G=G, K0=K0, points=POINTS)
    t = df["time_s"].to_numpy()
    s = df["granular_shear_stress_Pa"].to_numpy()
    ok = s > 1e-12 * stress0
    n = int(np.argmin(ok)) if not ok.all() else s.size
    n = max(n, 2)
    lns, d = np.log(np.maximum(s[:n], 1e-300)), -G * df["plastic_shear_rate_per_s"].to_numpy()[:n]
    d = d / np.maximum(s[:n], 1e-300)
    spline = CubicHermiteSpline(t[:n], lns, d)
    x = np.minimum(t_after[after], t[n - 1])
    ln[after] = spline(x) + d[-1] * (t_after[after] - x)
    slope[after] = np.where(t_after[after] > t[n - 1], d[-1], spline(x, 1))
    f = df["f"].to_numpy()
    return ln, slope, float(abs(f[-1] - f[0]))


def fit_relaxation(curves: list[RelaxationCurve], material, *, K0: float | None = None,
                   t0: float | None = None, confidence: float = 0.95,
                   name: str | None = None) -> RelaxationFit:
    """Fit G and K0 (and each curve's cessation time t0) to measured relaxations.

    Parameters
    ----------
    curves : list of RelaxationCurve
        At least 3 points each; phi below the material's phi_j; taubar0 > 0 with a flowing
        steady state.
    material : str or Material
        The steady fit (held parameters).
    K0 : float, optional
        Hold K0 at this value (fit only G and t0).
    t0 : float, optional
        Hold every curve's cessation time at this value [s] on its clock.
    confidence : float
        Level of the intervals, in (0.5, 1).

    Returns
    -------
    RelaxationFit
        ``material`` with G, K0 set; K keeps the material's K/G, else the K/G of the paper's
        Tables 4-7 (:data:`rheometer.material_point.K_OVER_G`): a shear relaxation does not
        measure it.

    Raises
    ------
    ValueError
        No curves, too few points, phi at or above phi_j, no flowing steady state at taubar0.
    RuntimeError
        The model fails at the start values (its diagnostics).
    """
    t_start = time.perf_counter()
    check_range("confidence", confidence, 0.5, 1.0, lo_closed=False, hi_closed=False)
    m = rheology.get_material(material)
    if not curves:
        raise ValueError("no relaxation curve to fit")
    if K0 is not None:
        check_range("K0", K0, 0.0, K0_MAX)
    eta_g, f0 = [], []
    for c in curves:
        if c.time.size < 3:
            raise ValueError(f"{c.label}: {c.time.size} kept point(s); at least 3 are needed")
        check_phi("phi", c.phi, m, where=f"{c.label}: ")
        check_range("--stress0", c.stress0, 0.0, STRESS_MAX, lo_closed=False,
                    note=f"{c.label}, Pa")
        st = rheology.steady_state_stress(c.stress0, c.phi, m)
        rate = float(st.shear_rate)
        if not (rate > 0 and np.isfinite(rate)) or bool(np.asarray(st.jammed)):
            raise ValueError(f"{c.label}: no flowing steady state at taubar0 = {c.stress0:g} Pa, "
                             f"phi = {c.phi:g} ({m.name} jams there): nothing relaxes from it")
        eta_g.append(c.stress0 / rate)
        f0.append(float(st.f))                       # the steady structure (Eq. 13)
    n_c = len(curves)
    fit_k0, fit_t0 = K0 is None, t0 is None
    names = ["G"] + ["K0"] * fit_k0 + [f"t0_{i + 1}" for i in range(n_c)] * fit_t0
    first = np.array([c.time.min() for c in curves])
    span = np.array([max(np.ptp(c.time), 1e-12) for c in curves])
    lo = np.array([np.log(G_RANGE[0])] + [np.log(K0_RANGE[0])] * fit_k0
                  + list(first - span) * fit_t0)
    hi = np.array([np.log(G_RANGE[1])] + [np.log(K0_RANGE[1])] * fit_k0
                  + list(first + 0.5 * span) * fit_t0)
    runs = [0]

    def unpack(th):
        G = float(np.exp(th[0]))
        k0 = float(np.exp(th[1])) if fit_k0 else float(K0)
        t0s = th[1 + fit_k0:] if fit_t0 else np.full(n_c, float(t0))
        return G, k0, t0s

    @functools.lru_cache(maxsize=64)
    def run(key: bytes) -> list:        # per curve: (ln data - ln model, its slope, change of f)
        G, k0, t0s = unpack(np.frombuffer(key))
        out = []
        for c, t_c in zip(curves, t0s):
            runs[0] += 1
            ln, sl, dfv = model_log_stress(m, c.phi, c.stress0, G, k0, c.time - t_c)
            out.append((np.log(c.stress) - ln, sl, dfv))
        return out

    def evaluate(th):                   # least_squares asks fun and jac at the same theta
        return run(np.asarray(th, float).tobytes())

    def fun(th):
        return np.concatenate([r for r, _, _ in evaluate(th)])

    def jac(th):                                     # ln G, ln K0: central differences
        J = central_jacobian(fun, th, lo, hi, 1e-4, relative=False, columns=1 + fit_k0)
        if fit_t0:                                   # t0: d(ln data - ln model)/dt0 = slope
            J = np.hstack([J, block_diag(*(e[1][:, None] for e in evaluate(th)))])
        return J

    # ------------------------------------------------------------ start
    G0 = []
    for c, eg in zip(curves, eta_g):
        ls = np.log(c.stress)
        below = np.flatnonzero(ls < ls[0] - 1.0)
        T = (c.time[below[0]] - c.time[0]) if below.size else (
            np.ptp(c.time) / max(ls[0] - ls[-1], 1e-3))
        G0.append(eg / max(T, 1e-12))
    G0 = float(np.exp(np.mean(np.log(G0))))

    def start_theta(G, k0):
        th = [np.log(G)] + [np.log(k0)] * fit_k0
        if fit_t0:          # cessation where the model passes the first reading
            for c, eg in zip(curves, eta_g):
                runs[0] += 1
                probe = relax(m, c.phi, c.stress0, 50.0 * eg / G, G=G, K0=k0, points=400)
                s = probe["granular_shear_stress_Pa"].to_numpy()
                k = int(np.argmax(s <= c.stress[0])) if (s <= c.stress[0]).any() else s.size - 1
                th.append(c.time[0] - float(probe["time_s"].iloc[k]))
        return np.clip(np.array(th, float), lo + 1e-6 * (hi - lo), hi - 1e-6 * (hi - lo))

    def start(g, k0):                   # (cost, theta, G, K0), None where the model fails
        th = start_theta(min(max(g, G_RANGE[0]), G_RANGE[1]), k0)
        try:
            return float(np.sum(fun(th) ** 2)), th, g, k0
        except RuntimeError:
            return None

    tries = [start(G0, k0) for k0 in ((0.01, 0.1, 1.0, 10.0, 100.0) if fit_k0 else (K0,))]
    tries = [t for t in tries if t is not None]            # K0 at G0, then G at the best K0
    if not tries:
        raise RuntimeError(f"the relaxation model fails at every start (G near {G0:.3g} Pa)")
    k_best = min(tries, key=lambda t: t[0])[3]
    tries += [t for t in (start(g, k_best) for g in (0.3 * G0, 3.0 * G0)) if t is not None]
    best = min(tries, key=lambda t: t[0])
    x_scale = np.array([1.0] * (1 + fit_k0) + list(0.1 * span) * fit_t0)
    res = least_squares(fun, best[1], jac=jac, bounds=(lo, hi), method="trf", x_scale=x_scale,
                        xtol=1e-10, ftol=1e-12, gtol=1e-10, max_nfev=200)
    # ------------------------------------------------------------ intervals and flags
    th = res.x
    G, k0, t0s = unpack(th)
    ev = evaluate(th)
    r = np.concatenate([e[0] for e in ev])
    dof = max(r.size - th.size, 1)
    s2 = float(np.sum(r ** 2)) / dof
    tq, sd, corr, active, degen = interval_statistics(jac(th), th, lo, hi, s2, dof, confidence)
    converged = bool(res.status > 0)
    delta_f = np.array([e[2] for e in ev])
    undecayed = [c.label for c in curves if c.stress.min() / c.stress0 > np.exp(-1.0)]
    params, messages, problems = [], [], []
    slow_f = delta_f.max() < 0.05 * max(f0)           # K0 acts through f only
    for k, p in enumerate(names):
        is_scale = p in SCALE
        value = float(np.exp(th[k])) if is_scale else float(th[k])
        at, bound = None, ""
        if active[k]:
            at_low = th[k] - lo[k] < 1e-7 * (hi[k] - lo[k])
            bound = "law" if (p == "K0" and at_low) else "search"
            at = (at_low, "at K0's floor: K0 = 0 within resolution, a frozen structure"
                  if bound == "law" else
                  f"at the fitter's {'lower' if at_low else 'upper'} search bound")
        # the offsets t0 trade with G by the model's form (a later cessation looks like a faster
        # decay when the record starts late): their marginal intervals carry it
        partners = [q for j, q in enumerate(names) if j != k and abs(corr[k, j]) > CORR_FLAG
                    and not active[j] and not active[k] and not q.startswith("t0")
                    and not p.startswith("t0")]
        extra = [f"{', '.join(undecayed)} end(s) before decaying below taubar0/e"] * bool(
            is_scale and undecayed)
        if p == "K0" and slow_f:
            extra.append(f"the structure f changes by at most {delta_f.max():.2g} over the "
                         "records (K0 acts only through it: larger taubar0/G, i.e. a softer "
                         "sample or a higher stress, shows it)")
        params.append(judged_estimate(
            p, value, th[k], sd[k], tq, "relaxation", log=is_scale, degenerate=bool(degen[k]),
            partners=partners, width=np.log(2.0) if is_scale else np.inf, at=at, bound=bound,
            converged=converged, extra=extra, messages=messages))
        if bound == "search":
            problems.append(f"{p} = {value:.4g} ended on the fitter's search bound, so the bound "
                            "and not the data sets it (check --material, --phi and --stress0 "
                            "of each curve, or hold it)")
    if not fit_k0:
        params.insert(1, ParameterEstimate("K0", float(K0), float(K0), float(K0), 0.0, "fixed",
                                           "fixed", "fixed", "held (--K0)"))
    if not converged:
        problems.append("the fit stopped at its evaluation limit before converging: its values "
                        "are not an optimum")
    sigma = float(np.sqrt(np.sum(r ** 2) / dof)) / np.log(10.0)
    if sigma > MISFIT_LOG10:
        problems.append(f"the model misses the records by a factor {10 ** min(sigma, 300):.3g} "
                        f"rms (sd {sigma:.3g} in log10 stress, more than {MISFIT_LOG10:g}): it "
                        "does not describe these data; check --stress0 (the steady stress "
                        "before cessation), --phi and --material of each curve")

    strain = max(c.stress0 for c in curves) / G
    if strain > ELASTIC_STRAIN_LIMIT:
        messages.append(f"taubar0/G = {strain:.3g} passes the small-elastic-strain limit "
                        f"{ELASTIC_STRAIN_LIMIT:g} of the hypoelastic law: the fit followed the "
                        "law past its range, and the command lines refuse runs there")
    ratio = (m.K / m.G) if (m.K is not None and m.G) else K_OVER_G
    fitted = m.replace(G=G, K0=k0, K=ratio * G, name=name or m.name,
                       notes=(m.notes + "; " if m.notes else "") + "G and K0 fitted by "
                       "rheometer.relaxation_fit to stress relaxation (Eqs. 35-37)")
    model = [np.exp(np.log(c.stress) - e[0]) for c, e in zip(curves, ev)]
    return RelaxationFit(fitted, params, curves, model,
                         [e[0] / np.log(10.0) for e in ev], np.asarray(t0s, float), delta_f,
                         sigma, converged, confidence, (names, corr), problems, messages,
                         runs[0], time.perf_counter() - t_start)


def synthetic_relaxation(m, phi: float, stress0: float, *, G: float, K0: float,
                         noise: float = 0.03, offset: float = 0.0, floor: float = 1e-3,
                         points: int = 200, seed: int = 0, t_end: float | None = None
                         ) -> RelaxationCurve:
    """A measured relaxation as a rheometer records it: :func:`rheometer.protocols.relax` at
    ``points`` output times, log-normal noise of standard deviation ``noise`` on the stress, the
    clock shifted so that cessation is at ``t0 = -offset`` (the record starts ``offset`` s after
    it: its first readings are lost), readings below ``floor`` taubar0 (the torque floor) cut.
    ``t_end`` defaults to the time the noise-free stress reaches ``floor`` taubar0."""
    rng = np.random.default_rng(seed)
    if t_end is None:
        eta = stress0 / float(rheology.steady_state_stress(stress0, phi, rheology.get_material(
            m)).shear_rate)
        probe = relax(m, phi, stress0, 50.0 * eta / G, G=G, K0=K0, points=400)
        s = probe["granular_shear_stress_Pa"].to_numpy()
        t_end = float(probe["time_s"].to_numpy()[np.argmax(s < floor * stress0)]) \
            if (s < floor * stress0).any() else float(probe["time_s"].iloc[-1])
    df = relax(m, phi, stress0, t_end, G=G, K0=K0, points=points)
    t, s = df["time_s"].to_numpy(), df["granular_shear_stress_Pa"].to_numpy()
    keep = (t >= offset) & (s > floor * stress0)
    meas = s[keep] * np.exp(noise * rng.standard_normal(int(keep.sum())))
    return RelaxationCurve(f"phi={phi:g} taubar0={stress0:g}", t[keep] - offset, meas,
                           float(phi), float(stress0))

