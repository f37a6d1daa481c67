"""The model fitted to measured steady flow curves: the Supplement's procedure, then a global fit.

Stages (Baumgarten & Kamrin, Supplement, Figs. 11-13):

1. (Fig. 11, Eq. 24) each curve's low-stress plateau (the minimum of a 3-point running mean of
   log viscosity) -> ``a0, phi_j`` with ``mu_c`` held, and ``eta0`` (the liquid's viscosity, the
   plateaus' dilute limit eta_r -> 1 + 5/2 phi) unless ``fixed``; three curves when eta0 is
   estimated.
2. (Fig. 12, Eq. 25) the high-stress plateau of the curves that thicken and flatten at the top of
   the ramp (log-log slope < 0.3) -> ``a_inf, phi_c``.
3. (Fig. 13, Eqs. 33-34) the DST rates of the curves whose rate saturates at the top (slope >
   0.6: phi above phi_c) -> eta_B(phi), one term (``varphi1, alpha1``, linear least squares in
   log) or two (``varphi2``, alpha2 held); tau* first fitted alone on the non-DST curves.
4. every free parameter together on all curves, the model at each measured MIXTURE stress
   (:func:`mixture_steady_state`), residuals in log10 viscosity, a soft-L1 loss against outliers
   (wall slip, artefacts); points beyond 4 robust standard deviations are then flagged outliers
   and plain least squares on the rest defines the confidence intervals.

Uncertainty: covariance s^2 (J^T J)^-1 at the optimum in the coordinates of :data:`SCALE` (ln for
scale parameters; :func:`jacobian_covariance`), Student-t intervals; for phi_j and phi_c the
profile likelihood (refits at fixed values until the sum of squares grows by s^2 t^2) replaces it.
Flags per parameter:

- ``at_bound``: it ended on a search bound (one-sided interval); a limit of the law itself
  (a_inf = a0, alpha_i = 0, Delta = 0 or 1) is a result, any other bound a problem;
- ``unidentifiable``: interval wider than a factor 2 (scale parameters), +-0.02 (fractions), +-1
  (exponents), unbounded or undefined (null), correlated beyond |r| = 0.99 with another (except
  pairs correlated by the equations' form: varphi_i with alpha_i, eta0 with a0 and a_inf), or
  along a direction of zero curvature;
- ``converged``: the optimiser stopped on its tolerances, not on its evaluation limit.

:func:`assess` words what makes a result unphysical. SI throughout; the model is the viscous
limit of Eq. (1) (grain inertia neglected, as in the paper's fits), honouring mu_2 and b.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numba as nb
import numpy as np
from numba.extending import register_jitable
from scipy import stats
from scipy.optimize import least_squares

import pandas as pd
from runkit.params import check_range

from . import laws
from .data import Curve, curve_table
from .materials import FIELD_UNITS, Material, get_material
from .numba_cache import guard
from .roots import brent
from .steady import gdot_dst

#: Every parameter the fitter can vary, with its reporting coordinate: "log" (intervals and
#: correlations in ln, always positive) or "lin".
SCALE: dict[str, str] = {
    "phi_j": "lin", "phi_c": "lin", "a0": "log", "a_inf": "log", "tau_star": "log",
    "varphi1": "log", "alpha1": "lin", "varphi2": "log", "alpha2": "lin", "eta0": "log",
    "mu_c": "log", "Delta": "lin",
}

#: Fitted by default (eta_B terms only as far as the data has DST curves).
DEFAULT_FREE: tuple[str, ...] = ("phi_j", "phi_c", "a0", "a_inf", "tau_star", "varphi1", "alpha1")

#: Held fixed by default; ``free=`` may add them.
OPTIONAL_FREE: tuple[str, ...] = ("eta0", "mu_c", "Delta", "varphi2", "alpha2")

#: |correlation| beyond which both parameters are flagged unidentifiable.
CORR_FLAG = 0.99
#: Pairs correlated by the form of the equations alone, not flagged for their mutual correlation
#: (their marginal intervals carry it): varphi_i with alpha_i (Eq. 34: varphi x^alpha pivots at
#: x = 1, far outside the data's phi_j - phi ~ 0.01-0.1), eta0 with a0 and a_inf (Eqs. 24-25:
#: near jamming the plateaus fix eta0 a^2 mu_c, the dilute terms 1 + 5/2 phi phi_m/(phi_m - phi)
#: separate them).
_PIVOT_PAIRS = ({"varphi1", "alpha1"}, {"varphi2", "alpha2"}, {"eta0", "a0"}, {"eta0", "a_inf"})

STAGE_OF = {"phi_j": "1", "a0": "1", "phi_c": "2", "a_inf": "2", "varphi1": "3", "alpha1": "3",
            "varphi2": "3", "alpha2": "3", "tau_star": "4", "eta0": "1", "mu_c": "4", "Delta": "4"}

#: The paper's fitted sets (Tables 1-3), whose span :func:`assess` takes as the plausible range.
PAPER_SETS: tuple[str, ...] = ("singh2018_a", "singh2018_b", "dhaene1993", "frith1996",
                               "guy2015_a", "guy2015_b", "fall2015", "hermes2016")
#: How far beyond the paper's span a0 and a_inf (factor) and phi_j - phi_c (factor) may go
#: before :func:`assess` calls them unphysical.
PLAUSIBLE_FACTOR = 2.0

guard(__file__)


# ============================================================================ the model at data
@register_jitable
def _contact_terms(u, phi, fhi, yhi, ef, dphi, a0, a_inf, mu_c, mu2, b):
    """(f, y, E, D) at f = u f_hi: the gap y = phi_m(f) - phi, E = 2 mu (a phi)^2 + 5/2 phi^2 y
    and D = (1 + 5/2 phi) y^2 + E (taubar = tau E/D; numpy arrays or, in numba, scalars)."""
    f = u * fhi
    y = yhi + dphi * fhi * (1.0 - u)
    a = laws.dilatancy_a(f, a0, a_inf)
    mu = laws.critical_friction(phi, y, a, mu_c, mu2, b)
    E = 2.0 * mu * (a * phi) ** 2 + 2.5 * phi * phi * y
    return f, y, E, ef * y * y + E


@nb.njit(cache=True, error_model="numpy")
def _structure_residual(u, tau, phi, fm, fhi, yhi, inv, ef, dphi, a0, a_inf, mu_c, mu2, b,
                        tau_star, eta0, xi):
    """y^2 [f (H + S) - H f_m] at f = u f_hi for imposed mixture stress tau (viscous limit)."""
    f, y, E, D = _contact_terms(u, phi, fhi, yhi, ef, dphi, a0, a_inf, mu_c, mu2, b)
    H = laws.hardening(tau * E / D, tau_star)
    y2 = y * y
    return f * ((H + 1.0) * y2 + eta0 * inv * E + xi * eta0 * D / tau) - H * fm * y2


@nb.njit(cache=True, error_model="numpy")
def _solve_structure(tau, phi, fm, fhi, yhi, inv, ef, dphi, a0, a_inf, mu_c, mu2, b, tau_star,
                     eta0, xi):
    """u in [0, 1] per point by Brent's method (rheology.roots.brent); NaN where no sign change."""
    out = np.empty(tau.size)
    for i in range(tau.size):
        args = (tau[i], phi[i], fm[i], fhi[i], yhi[i], inv[i], ef[i], dphi, a0, a_inf, mu_c,
                mu2, b, tau_star, eta0, xi)
        fa = _structure_residual(0.0, *args)
        fb = _structure_residual(1.0, *args)
        if fa == 0.0 or fb == 0.0:
            out[i] = 0.0 if fa == 0.0 else 1.0
        elif (fa > 0.0) == (fb > 0.0):
            out[i] = np.nan
        else:
            out[i] = brent(_structure_residual, args, 0.0, 1.0, fa, fb, 4.440892098500626e-16,
                           0.5e-16, 0.0, 300)[0]        # rtol: 2 machine epsilons
    return out


def mixture_steady_state(tau, phi, m: Material) -> dict[str, np.ndarray]:
    """Steady simple shear at imposed MIXTURE shear stress, viscous limit (Eqs. 1, 3-9, 13).

    The structure f fixes gdot = tau/(eta0 (1 + 5/2 phi + eta_g)) and taubar = eta0 eta_g gdot;
    f solves ``y^2 [f (H + S) - H f_m] = 0`` (y = phi_m(f) - phi), bracketed on
    [0, min(f_m, f_jam)] (negative at 0), by Brent's method per point (numba). Agrees with
    :func:`rheology.steady.steady_states_mixture_stress` (~1e-14 where that finds one state) at
    a fraction of its cost.

    Parameters
    ----------
    tau : array_like
        Mixture shear stress [Pa], > 0.
    phi : array_like
        Volume fraction, 0 < phi < phi_j (broadcast with tau).

    Returns
    -------
    dict of arrays (broadcast shape)
        ``f``, ``gap`` (phi_m - phi), ``shear_rate`` [1/s], ``viscosity`` [Pa s] (huge but
        finite at jamming), ``taubar`` [Pa], ``log10_viscosity``.

    Raises
    ------
    ValueError
        tau <= 0 or non-finite, phi outside (0, phi_j).
    RuntimeError
        The bracketed solve fails (names the first failing point).
    """
    tau = check_range("tau", tau, 0.0, None, lo_closed=False)
    phi = check_range("phi", phi, 0.0, m.phi_j, lo_closed=False, hi_closed=False,
                      note=f"steady flow needs phi below phi_j = {m.phi_j:.6g}")
    shape = np.broadcast_shapes(np.shape(tau), np.shape(phi))
    tau, phi = (np.ravel(x).astype(float) for x in np.broadcast_arrays(tau, phi))
    dphi = m.phi_j - m.phi_c
    fm = laws.f_max(phi, m.phi_c, m.phi_j, m.Delta)
    fjam = (m.phi_j - phi) / dphi
    fhi = np.minimum(fm, fjam)
    yhi = np.where(fm < fjam, (m.phi_j - phi) - dphi * fm, 0.0)
    inv = laws.inv_eta_B(phi, m.phi_j, m.varphi1, m.alpha1, m.varphi2, m.alpha2)
    ef = 1.0 + 2.5 * phi

    contact = (float(m.a0), float(m.a_inf), float(m.mu_c), float(m.mu2), float(m.b))
    u = _solve_structure(tau, phi, fm, fhi, yhi, inv, ef, dphi, *contact, float(m.tau_star),
                         float(m.eta0), float(m.xi_eps))
    if not np.all(np.isfinite(u)):
        k = int(np.flatnonzero(~np.isfinite(u))[0])
        raise RuntimeError(f"mixture-stress steady solve failed at tau = {tau[k]:.6g} Pa, phi = "
                           f"{phi[k]:.6g} (no sign change of the structure residual)")
    f, y, E, D = _contact_terms(u, phi, fhi, yhi, ef, dphi, *contact)
    ys = np.maximum(y, 1e-150)
    rel = ef + E / (ys * ys)
    out = {"f": f, "gap": y, "viscosity": m.eta0 * rel, "shear_rate": tau / (m.eta0 * rel),
           "taubar": tau * E / np.maximum(D, 1e-300), "log10_viscosity": np.log10(m.eta0 * rel)}
    return {k: v.reshape(shape) for k, v in out.items()}


# ============================================================================ data
@dataclass
class FlowData:
    """Measured steady flow curves, kept points only (SI).

    Attributes
    ----------
    stress, rate, viscosity, phi : float arrays
        Mixture shear stress [Pa], shear rate [1/s], viscosity [Pa s], volume fraction.
    curve : int array
        Curve index of each point (0 .. n_curves-1), in order of first appearance.
    labels : list of str
        One label per curve (file and interval).
    """

    stress: np.ndarray
    rate: np.ndarray
    viscosity: np.ndarray
    phi: np.ndarray
    curve: np.ndarray
    labels: list[str] = field(default_factory=list)

    @classmethod
    def from_table(cls, table) -> "FlowData":
        """From the tidy table of :func:`rheology.data.read_flow_curves` (kept rows only).
        Raises ValueError if a kept row has no volume fraction."""
        t = table[table["kept"]]
        if t["phi"].isna().any():
            bad = t.loc[t["phi"].isna(), "source_file"].iloc[0]
            raise ValueError(f"data file {bad!r} carries no volume fraction: give --phi")
        keys = ["source_file", "interval", "phi"]
        curve = t.groupby(keys, sort=False).ngroup().to_numpy()       # in order of appearance
        labels = [f"{s} [{i}] phi={p:.4g}" for s, i, p in t[keys].drop_duplicates().to_numpy()]
        return cls(t["shear_stress_Pa"].to_numpy(float), t["shear_rate_per_s"].to_numpy(float),
                   t["viscosity_Pa_s"].to_numpy(float), t["phi"].to_numpy(float), curve, labels)

    @classmethod
    def from_arrays(cls, stress, viscosity, phi, curve=None) -> "FlowData":
        stress, viscosity, phi = (np.asarray(x, float) for x in (stress, viscosity, phi))
        if curve is None:
            _, curve = np.unique(phi, return_inverse=True)
        curve = np.asarray(curve, int)
        labels = [f"phi={phi[curve == c][0]:.4g}" for c in range(curve.max() + 1)]
        return cls(stress, stress / viscosity, viscosity, phi, curve, labels)

    @property
    def n_curves(self) -> int:
        return int(self.curve.max()) + 1

    def curve_phi(self) -> np.ndarray:
        return np.array([self.phi[self.curve == c][0] for c in range(self.n_curves)])

    def sorted_curve(self, c: int):
        """(stress, viscosity, rate) of curve c, sorted by stress."""
        sel = np.flatnonzero(self.curve == c)
        o = sel[np.argsort(self.stress[sel])]
        return self.stress[o], self.viscosity[o], self.rate[o]


# ============================================================================ stages 1-3
@dataclass
class CurveFeatures:
    """What stages 1-3 read from one curve.

    eta_min : low-stress plateau [Pa s] (minimum of the 3-point running mean in log)
    eta_max : high-stress plateau [Pa s] (maximum of the same), meaningful if ``kind == 'plateau'``
    top_slope : d log(viscosity)/d log(stress) over the top quarter of the ramp
    kind : 'plateau' (stage 2), 'dst' (stage 3), 'jamming' (the rate falls: eta_B = inf) or
        'neither'
    gdot_dst : DST rate [1/s] (median rate of the top quarter), for kind 'dst'
    stress_min, stress_max : where the plateau minimum and maximum were read [Pa]
    dst_stress : (lowest, highest) stress of the top quarter, where the DST rate was read [Pa]
    """

    phi: float
    eta_min: float
    eta_max: float
    top_slope: float
    kind: str
    gdot_dst: float
    stress_min: float
    stress_max: float
    dst_stress: tuple[float, float]


def curve_features(data: FlowData, *, plateau_slope: float = 0.3, dst_slope: float = 0.6,
                   thickening: float = 1.2) -> list[CurveFeatures]:
    """Classify every curve and read its plateaus and DST rate (stages 1-3 inputs).

    A curve has a high-stress plateau when the log-log slope of viscosity against stress over the
    top quarter of its stress range (at least 4 points) is below ``plateau_slope`` and its
    maximum is ``thickening`` times its minimum; it is a DST curve when that slope exceeds
    ``dst_slope`` (the shear rate saturates).
    """
    def running_mean(x):                            # of 3 points
        return x.copy() if x.size < 3 else np.convolve(x, np.ones(3) / 3, mode="valid")

    out = []
    for c, phi in enumerate(data.curve_phi()):
        s, v, r = data.sorted_curve(c)
        ls, lv = np.log(s), np.log(v)
        sm, ss = running_mean(lv), running_mean(ls)
        kmin, kmax = int(np.argmin(sm)), int(np.argmax(sm))
        top = ls >= ls[-1] - 0.25 * (ls[-1] - ls[0])
        if top.sum() < 4:
            top = np.zeros_like(top)
            top[-min(4, top.size):] = True
        slope = float(np.polyfit(ls[top], lv[top], 1)[0]) if top.sum() >= 2 else 0.0
        thick = np.exp(sm[kmax] - sm[kmin]) >= thickening
        kind = ("plateau" if slope < plateau_slope and thick and kmax > kmin else
                "dst" if dst_slope < slope < 2.0 - dst_slope else   # the rate saturates (slope 1)
                "jamming" if slope >= 2.0 - dst_slope else "neither")   # ... or falls
        g = float(np.exp(np.median(np.log(r[top])))) if kind == "dst" else float("nan")
        out.append(CurveFeatures(float(phi), float(np.exp(sm[kmin])),
                                 float(np.exp(sm[kmax])), slope, kind, g, float(np.exp(ss[kmin])),
                                 float(np.exp(ss[kmax])),
                                 (float(s[top].min()), float(s[top].max()))))
    return out


def plateau_viscosity(phi, pm, a, mu_c):
    """Relative viscosity of a plateau, Eqs. (24)-(25): 1 + 5/2 phi pm/(pm - phi) + 2 mu_c
    (a phi/(pm - phi))^2; pm = phi_j, a = a0 at low stress, pm = phi_c, a = a_inf at high stress
    (0 < phi < pm)."""
    return 1 + 2.5 * phi * pm / (pm - phi) + 2 * mu_c * (a * phi / (pm - phi)) ** 2


def _plateau_fit(phi, eta, mu_c, pm, a, pm_range, a_range, *, fit_pm=True, fit_a=True,
                 eta0=1.0):
    """Least squares in log viscosity of eta = eta0 [1 + 5/2 phi pm/(pm - phi) + 2 mu_c (a phi /
    (pm - phi))^2] (Eq. 24 with pm = phi_j, a = a0; Eq. 25 with pm = phi_c, a = a_inf), from the
    start (pm, a), each fitted or held; ``eta0=None`` estimates eta0 too (the mean log misfit,
    profiled out). Returns (pm, a, eta0)."""
    phi, eta = np.asarray(phi, float), np.asarray(eta, float)

    def unpack(x):
        return (x[0] if fit_pm else pm), (np.exp(x[-1]) if fit_a else a)

    def log_ratio(x):                     # ln(eta_r of the model / eta measured)
        return np.log(plateau_viscosity(phi, *unpack(x), mu_c)) - np.log(eta)

    def misfit(x):
        r = log_ratio(x)
        return r - r.mean() if eta0 is None else r + np.log(eta0)

    x = np.array([pm] * fit_pm + [np.log(a)] * fit_a, float)
    if x.size:
        lo = [pm_range[0]] * fit_pm + [np.log(a_range[0])] * fit_a
        hi = [pm_range[1]] * fit_pm + [np.log(a_range[1])] * fit_a
        x = least_squares(misfit, x, bounds=(lo, hi), x_scale=[0.01] * fit_pm + [0.1] * fit_a).x
    p, q = unpack(x)
    return float(p), float(q), float(eta0 if eta0 is not None else np.exp(-log_ratio(x).mean()))


def _clip_inside(x, lo, hi):
    span = hi - lo
    return float(min(max(x, lo + 1e-3 * span), hi - 1e-3 * span))


# ============================================================================ parametrisation
#: Search box in the optimiser's coordinates (ln for log-scale parameters) where no other free
#: parameter sets it.
_BOX = {"tau_star": (np.log(1e-8), np.log(1e9)), "varphi1": (-120.0, 120.0),
        "varphi2": (-120.0, 120.0), "a0": (np.log(1e-3), np.log(1e2)),
        "eta0": (np.log(1e-8), np.log(1e4)), "mu_c": (np.log(1e-3), np.log(1e2)),
        "alpha1": (0.0, 30.0), "alpha2": (0.0, 30.0), "Delta": (0.0, 1.0)}


class _Params:
    """Free parameters <-> the optimiser's box coordinates theta: (phi_j, phi_j - phi_c) and
    (ln a0, ln(a_inf/a0) >= 0) when both are free (the orderings become box bounds), scale
    parameters in ln, exponents and Delta linear."""

    def __init__(self, base: Material, free: list[str], phi_max: float):
        self.base, self.free, self.phi_max = base, list(free), phi_max
        free = self.free
        self.pair = {"phi_c": "phi_j" in free and "phi_c" in free,
                     "a_inf": "a0" in free and "a_inf" in free}
        box = {"phi_j": ("phi_j", max(phi_max, 0.0 if "phi_c" in free else base.phi_c) + 1e-5,
                         0.9999),
               "phi_c": ("dphi", 1e-4, phi_max) if "phi_j" in free     # phi_c > phi_j - phi_max
               else ("phi_c", 1e-4, base.phi_j - 1e-4),
               "a_inf": ("ln_ainf_over_a0", 0.0, np.log(100.0)) if "a0" in free
               else ("ln_a_inf", np.log(base.a0), np.log(1e3)),
               "a0": ("ln_a0", *_BOX["a0"]) if "a_inf" in free
               else ("ln_a0", np.log(1e-3), np.log(base.a_inf))}
        rows = [box.get(p) or (("ln_" if SCALE[p] == "log" else "") + p, *_BOX[p]) for p in free]
        self.names = [r[0] for r in rows]
        self.lo, self.hi = (np.array([r[i] for r in rows], float) for i in (1, 2))
        # which bound is a limit of the law, not the search's
        self.physical_lo = np.array([p in ("alpha1", "alpha2", "Delta") or self.pair["a_inf"]
                                     and p == "a_inf" for p in free], bool)
        self.physical_hi = np.array([p == "Delta" for p in free], bool)

    def values(self, theta) -> dict[str, float]:
        v = {p: float(np.exp(x)) if SCALE[p] == "log" else float(x)
             for p, x in zip(self.free, theta)}
        if self.pair["phi_c"]:                      # theta holds phi_j - phi_c, ln(a_inf/a0)
            v["phi_c"] = v["phi_j"] - float(theta[self.free.index("phi_c")])
        if self.pair["a_inf"]:
            v["a_inf"] = v["a0"] * float(np.exp(theta[self.free.index("a_inf")]))
        return v

    def theta(self, m: Material) -> np.ndarray:
        th = np.array([m.phi_j - m.phi_c if p == "phi_c" and self.pair["phi_c"] else
                       np.log(m.a_inf / m.a0) if p == "a_inf" and self.pair["a_inf"] else
                       np.log(getattr(m, p)) if SCALE[p] == "log" else getattr(m, p)
                       for p in self.free], float)
        span = self.hi - self.lo
        return np.clip(th, self.lo + 1e-9 * span, self.hi - 1e-9 * span)

    def material(self, theta) -> Material:
        return dataclasses.replace(self.base, **self.values(theta))

    def psi(self, theta) -> np.ndarray:
        """Reporting coordinates (ln for log-scale parameters) of the free parameters."""
        v = self.values(theta)
        return np.array([np.log(v[p]) if SCALE[p] == "log" else v[p] for p in self.free])


# ============================================================================ results
@dataclass
class ParameterEstimate:
    """One parameter of a fit: value, interval (NaN where unbounded or undefined: written as
    null), its standard error in the reporting coordinate (ln for log-scale parameters), the
    interval's method ("jacobian", "profile", "fixed", "none"), stage, the three flags (module
    docstring) and a note on them. ``status`` summarises: "fixed", "fitted" or the raised flags
    joined by "+" ("at_bound", "unidentifiable", "not_converged")."""

    name: str
    value: float
    lower: float
    upper: float
    std_error: float
    method: str
    stage: str
    status: str = ""
    note: str = ""
    at_bound: bool = False
    unidentifiable: bool = False
    converged: bool = True
    bound: str = ""           # at_bound: "law" (a limit of the law itself) or "search"

    def __post_init__(self):
        if self.status not in ("fixed", "stages 1-3"):
            flags = [f for f, on in (("at_bound", self.at_bound),
                                     ("unidentifiable", self.unidentifiable),
                                     ("not_converged", not self.converged)) if on]
            self.status = "+".join(flags) or "fitted"


def parameter_table(params, scale: dict[str, str], units: dict[str, str]):
    """parameters.csv of a fit as a DataFrame: ``parameter, value, unit, lower, upper,
    std_error_reporting_coord, reporting_coord, interval, stage, status, at_bound,
    unidentifiable, converged, note`` (non-finite lower, upper, std_error as NaN: empty cells)."""
    def fin(x):
        return float(x) if np.isfinite(x) else float("nan")

    return pd.DataFrame([{"parameter": p.name, "value": p.value, "unit": units.get(p.name, "-"),
                          "lower": fin(p.lower), "upper": fin(p.upper),
                          "std_error_reporting_coord": fin(p.std_error),
                          "reporting_coord": scale.get(p.name, "lin"), "interval": p.method,
                          "stage": p.stage, "status": p.status, "at_bound": p.at_bound,
                          "unidentifiable": p.unidentifiable, "converged": p.converged,
                          "note": p.note} for p in params])


#: Columns of :func:`parameter_table` that may be empty (an interval unbounded or undefined).
PARAMETER_EMPTY_OK = ("lower", "upper", "std_error_reporting_coord")


def jacobian_covariance(J: np.ndarray, theta: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                        s2: float, rcond: float = 1e-9):
    """Covariance of least-squares estimates from the Jacobian at the optimum.

    Parameters
    ----------
    J : (n_points, n_parameters) array
        Jacobian of the residuals in the optimiser's coordinates theta.
    theta, lo, hi : (n_parameters,) arrays
        Optimum and box bounds.
    s2 : float
        Residual variance (sum of squares / degrees of freedom).

    Returns
    -------
    cov : (n, n) array
        s^2 (J^T J)^-1 over the interior parameters (pseudo-inverse: singular values below
        ``rcond`` times the largest dropped), and for parameters at a bound their variance from
        the pseudo-inverse of the full J.
    active : bool array
        At a bound (within 1e-7 of its span).
    degenerate : bool array
        Loading (> 0.1) on a direction of no curvature (dropped singular value).
    """
    n = theta.size
    span = hi - lo
    active = (theta - lo < 1e-7 * span) | (hi - theta < 1e-7 * span)
    cov = np.zeros((n, n))
    degenerate = np.zeros(n, bool)
    keep = ~active
    if keep.any():
        _, sv, Vt = np.linalg.svd(J[:, keep], full_matrices=False)
        tiny = ~(sv >= rcond * sv[0]) if sv[0] > 0 else np.ones_like(sv, bool)
        inv_s2 = np.where(tiny, 0.0, 1.0 / np.where(tiny, 1.0, sv) ** 2)
        idx = np.flatnonzero(keep)
        cov[np.ix_(idx, idx)] = s2 * (Vt.T * inv_s2) @ Vt
        for row in Vt[tiny]:
            degenerate[idx[np.abs(row) > 0.1]] = True
    _, svf, Vtf = np.linalg.svd(J, full_matrices=False)
    okf = svf > rcond * svf[0] if svf[0] > 0 else np.zeros_like(svf, bool)
    cov_full = s2 * (Vtf.T[:, okf] / svf[okf] ** 2) @ Vtf[okf]
    for k in np.flatnonzero(active):
        cov[k, k] = cov_full[k, k]
        # a parameter that ran to a bound along a direction the data do not see (mu_c with a0,
        # a_inf: Eq. 1 holds only mu_c a^2) is unidentifiable, not merely at a bound
        if np.any(np.abs(Vtf[~okf, k]) > 0.1):
            degenerate[k] = True
    return cov, active, degenerate


def interval_statistics(J, theta, lo, hi, s2: float, dof: int, confidence: float, L=None):
    """The Student-t quantile, standard deviations, correlations, bound and degeneracy flags of
    estimates ``L theta`` (``L``: the Jacobian of the reported parameters in theta, default
    the identity) from :func:`jacobian_covariance`: ``(tq, sd, corr, active, degenerate)``,
    ``corr`` 0 where undefined and 1 on its diagonal."""
    tq = float(stats.t.ppf(0.5 + confidence / 2, dof))
    cov, active, degenerate = jacobian_covariance(J, theta, lo, hi, s2)
    if L is not None:
        cov = L @ cov @ L.T
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sd, sd)
    corr = np.where(np.isfinite(corr), corr, 0.0)
    np.fill_diagonal(corr, 1.0)
    return tq, sd, corr, active, degenerate


def log_interval(lo: float, hi: float) -> tuple[float, float]:
    """An interval in ln x as one in x: an end at 0 or inf is unbounded (NaN)."""
    with np.errstate(over="ignore", invalid="ignore"):
        return tuple(float(x) if 0 < x < np.inf else np.nan for x in np.exp([lo, hi]))


@dataclass
class FitResult:
    """What :func:`fit_flow_curves` returns.

    material : the fitted Material (validated)
    parameters : ParameterEstimate per parameter (free first, then held)
    correlation : (names, matrix) of the free parameters in reporting coordinates
    stages : per stage, a dict of what was read and fitted (curve features, estimates)
    residual_log10 : log10(measured/model viscosity) per data point
    outlier : bool per point (excluded from the polish and the intervals)
    model_viscosity, model_rate : at each measured stress
    sigma_log10 : residual standard deviation of the inliers
    n_evaluations : model evaluations (one = all points through mixture_steady_state)
    seconds : wall time of the fit
    messages : warnings for the user (unidentifiable parameters, stages skipped)
    converged : the global fit stopped on its tolerances (not its evaluation limit)
    problems : what makes the result unphysical (:func:`assess`); empty for a trustworthy fit
    """

    material: Material
    parameters: list[ParameterEstimate]
    correlation: tuple[list[str], np.ndarray]
    stages: dict
    residual_log10: np.ndarray
    outlier: np.ndarray
    model_viscosity: np.ndarray
    model_rate: np.ndarray
    sigma_log10: float
    n_evaluations: int
    seconds: float
    messages: list[str]
    confidence: float
    converged: bool = True
    problems: list[str] = field(default_factory=list)

    def parameter(self, name: str) -> ParameterEstimate:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def table(self):
        """parameters.csv as a DataFrame (:func:`parameter_table`)."""
        return parameter_table(self.parameters, SCALE, FIELD_UNITS)


# ============================================================================ the fitter
def fit_flow_curves(data: FlowData, start: Material | str = "hermes2016", *,
                    fixed: dict[str, float] | None = None, free: list[str] | None = None,
                    etaB_terms: int | None = None, confidence: float = 0.95, profile: bool = True,
                    f_scale: float | None = None, name: str = "fit",
                    citation: str = "", stages_only: bool = False) -> FitResult:
    """Fit the model to measured steady flow curves (stages 1-4; see the module docstring).

    Parameters
    ----------
    data : FlowData
        Kept points of the measured curves (at least 2 curves for stage 1).
    start : Material or str
        Starting point and source of the held parameters (mu_c, Delta, alpha2 by default).
    fixed : dict, optional
        Parameters fixed at the given values (``--set NAME=VALUE``), applied to ``start`` first.
        ``eta0`` (the suspending liquid's viscosity) is estimated from the data unless fixed
        here; the start's eta0 is never used silently.
    free : list of str, optional
        Parameters of :data:`OPTIONAL_FREE` also to fit (``--free``).
    etaB_terms : int, optional
        1 or 2 terms in Eq. (34) (two need at least 3 DST curves; alpha2 held unless freed);
        default: as many as the start material has.
    confidence : float
        Level of the intervals, in (0.5, 1).
    profile : bool
        Profile-likelihood intervals for phi_j and phi_c (about 10 refits).
    f_scale : float, optional
        Soft-L1 scale in log10 viscosity; default 3 robust standard deviations of a first pass.
    stages_only : bool
        Stop after stage 3 (the Supplement's procedure alone; no intervals).

    Returns
    -------
    FitResult

    Raises
    ------
    ValueError
        Fewer than two curves (three when eta0 is estimated), a parameter name not fittable,
        fixed values out of range, a volume fraction at or above the start's bounds that no fit
        can reach.
    RuntimeError
        The optimiser fails (its message).
    """
    t0 = time.perf_counter()
    check_range("confidence", confidence, 0.5, 1.0, lo_closed=False, hi_closed=False)
    base = get_material(start)
    if etaB_terms is None:
        etaB_terms = 2 if base.varphi2 > 0 else 1
    if etaB_terms not in (1, 2):
        raise ValueError(f"etaB_terms = {etaB_terms} must be 1 or 2")
    fixed = dict(fixed or {})
    if fixed:
        base = base.replace(**fixed)
    free_extra = list(free or [])
    bad = [p for p in free_extra if p not in SCALE]
    if bad:
        raise ValueError(f"--free {' '.join(bad)}: cannot be fitted; fittable: "
                         f"{', '.join(SCALE)}")
    if data.n_curves < 2:
        raise ValueError(f"{data.n_curves} flow curve(s): the fit needs at least 2 volume "
                         "fractions (stage 1 fits two parameters to one plateau per curve)")
    estimate_eta0 = "eta0" not in fixed
    if estimate_eta0 and data.n_curves < 3:
        raise ValueError(f"eta0 (the suspending liquid's viscosity) is estimated with phi_j and a0 "
                         f"from one low-stress plateau per curve: {data.n_curves} curves cannot "
                         "give three parameters; give it with --set eta0=VALUE (Pa s, measured "
                         "on the liquid alone) or add curves")
    counts = np.bincount(data.curve)
    if counts.min() < 3:
        raise ValueError(f"curve {data.labels[int(np.argmin(counts))]} has {counts.min()} kept "
                         "point(s): at least 3 are needed")
    messages: list[str] = []
    n_eval = [0]
    phis = data.curve_phi()
    phi_max = float(phis.max())
    logeta = np.log10(data.viscosity)

    def model(m: Material, sel=slice(None)):
        n_eval[0] += 1
        return mixture_steady_state(data.stress[sel], data.phi[sel], m)

    # ---------------------------------------------------------------- stage 1 (Eq. 24)
    feats = curve_features(data)
    mu_c = base.mu_c
    eta_min = np.array([f.eta_min for f in feats])
    pj0 = base.phi_j if base.phi_j > phi_max else phi_max + 0.02
    if "phi_j" in fixed and "a0" in fixed and not estimate_eta0:
        messages.append("stage 1 skipped: phi_j and a0 both fixed")
    phi_j, a0, eta0 = _plateau_fit(
        phis, eta_min, mu_c, base.phi_j if "phi_j" in fixed else _clip_inside(pj0, phi_max, 0.9999),
        base.a0, (phi_max + 1e-5, 0.9999), (1e-3, 100.0), fit_pm="phi_j" not in fixed,
        fit_a="a0" not in fixed, eta0=None if estimate_eta0 else base.eta0)
    base = base.replace(eta0=eta0)
    stage1 = {"phi": phis, "eta_min": eta_min, "stress_min": [f.stress_min for f in feats],
              "phi_j": phi_j, "a0": a0, "mu_c": mu_c, "eta0": eta0,
              "eta0_estimated": estimate_eta0}

    # ---------------------------------------------------------------- stage 2 (Eq. 25)
    plat = [i for i, f in enumerate(feats) if f.kind == "plateau"]
    dst = [i for i, f in enumerate(feats) if f.kind == "dst"]
    phi_c_hi = min([phis[i] for i in dst] + [phi_j - 1e-4])
    phi_c = base.phi_c - base.phi_j + phi_j
    a_inf = base.a_inf if "a_inf" in fixed else max(a0, a0 * (base.a_inf / base.a0))
    eta_r_max = np.array([feats[i].eta_max for i in plat]) / eta0
    lo = float(phis[plat].max()) + 1e-5 if plat else 0.0       # phi_c above every plateau's phi
    box = (lo, max(phi_c_hi, lo + 2e-5))

    def plateau(pm, a, pm_range=box, a_range=(a0, 100.0), **kw):
        return _plateau_fit(phis[plat], eta_r_max, mu_c, pm, a, pm_range, a_range, **kw)

    if "phi_c" in fixed:
        phi_c = base.phi_c
        if plat and "a_inf" not in fixed:
            a_inf = max(a0, plateau(phi_c, a_inf, (0, 1), (1e-3, 1e3), fit_pm=False)[1])
        if not plat:
            messages.append("stage 2: phi_c fixed, no high-stress plateau to fit a_inf")
    elif len(plat) >= 2 and "a_inf" not in fixed:
        phi_c, a_inf, _ = plateau(_clip_inside(phi_c, *box), max(a_inf, a0 * 1.0001))
    elif plat:
        phi_c = plateau(_clip_inside(phi_c, *box), a_inf, fit_a=False)[0]
        messages.append(f"stage 2: one high-stress plateau only: a_inf starts at {a_inf:.4g} "
                        "(the start's a_inf/a0) and only phi_c is fitted here"
                        + ("; a_inf stays fixed" if "a_inf" in fixed else
                           "; stage 4 fits a_inf with the rest (its status is in the table)"))
    else:
        phi_c = _clip_inside(phi_c, 1e-3, phi_c_hi)
        messages.append("stage 2: no curve with a high-stress plateau: phi_c and a_inf start "
                        "from the start material's (phi_j - phi_c, a_inf/a0) and are left to "
                        "stage 4")
    phi_c, a_inf = min(phi_c, phi_j - 1e-4), max(a_inf, a0)
    stage2 = {"phi": phis[plat] if plat else np.zeros(0), "eta_max": eta_r_max * eta0,
              "stress_max": [feats[i].stress_max for i in plat], "phi_c": phi_c, "a_inf": a_inf,
              "curves": plat}
    m = dataclasses.replace(base, phi_j=phi_j, phi_c=phi_c, a0=a0, a_inf=a_inf)

    # ---------------------------------------------------------------- stage 3 (Eqs. 33-34)
    if "tau_star" not in fixed:             # tau* first, on the curves without DST
        sel = np.isin(data.curve, [i for i, f in enumerate(feats) if f.kind != "dst"])
        if sel.sum() < 3:
            sel = np.ones_like(data.curve, dtype=bool)
        sel &= data.phi < m.phi_j
        lt = least_squares(lambda x: logeta[sel] - model(
            dataclasses.replace(m, tau_star=float(np.exp(x[0]))), sel)["log10_viscosity"],
            [np.log(m.tau_star)], bounds=([np.log(1e-8)], [np.log(1e9)]), loss="soft_l1",
            f_scale=0.05)
        m = dataclasses.replace(m, tau_star=float(np.exp(lt.x[0])))
    dst_ok = [i for i in dst if m.phi_c <= phis[i] < m.phi_j]
    if len(dst_ok) < len(dst):
        messages.append(f"stage 3: {len(dst) - len(dst_ok)} DST curve(s) below the stage-2 "
                        "phi_c left out of Eq. (33)")
    g = np.array([feats[i].gdot_dst for i in dst_ok])
    phd = phis[dst_ok] if dst_ok else np.zeros(0)
    v1, al1, v2, al2 = m.varphi1, m.alpha1, m.varphi2 * (etaB_terms == 2), m.alpha2
    if dst_ok and not {"varphi1", "alpha1"} <= set(fixed):
        x = m.phi_j - phd
        a = laws.dilatancy_a(laws.f_max(phd, m.phi_c, m.phi_j, m.Delta), m.a0, m.a_inf)
        # Eq. (33) solved for 1/eta_B at each DST rate
        inv_target = (2 * m.mu_c) ** 0.5 * (a * phd / x) / m.eta0 * (
            m.tau_star / (m.eta0 * g)) ** -1.5
        if etaB_terms == 2 and (len(dst_ok) >= 3 or len(dst_ok) == 2 and np.ptp(np.log(x)) > 0):
            three = len(dst_ok) >= 3          # alpha1 fitted too; two curves: both alphas held
            q = least_squares(lambda q: np.log(np.exp(q[0]) * x ** (q[1] if three else al1)
                                               + np.exp(q[-1]) * x ** al2) - np.log(inv_target),
                              [np.log(max(v1, 1e-30)), *[al1] * three,
                               np.log(max(v2, 1e-30) if v2 > 0 else 1e-3)],
                              bounds=([-120, *[0] * three, -120], [120, *[30] * three, 120])).x
            v1, v2, al1 = float(np.exp(q[0])), float(np.exp(q[-1])), float(q[1]) if three else al1
            if not three:
                messages.append("stage 3: two DST curves for two eta_B terms: alpha1, alpha2 held "
                                f"at {al1:.4g}, {al2:.4g}")
        elif len(dst_ok) >= 2 and "alpha1" not in fixed and np.ptp(np.log(x)) > 0:
            coef = np.linalg.lstsq(np.column_stack([np.ones_like(x), np.log(x)]),
                                   np.log(inv_target), rcond=None)[0]
            v1, al1 = float(np.exp(coef[0])), float(np.clip(coef[1], 0.0, 30.0))
        else:
            v1 = float(np.exp(np.mean(np.log(inv_target) - al1 * np.log(x))))
            messages.append(f"stage 3: one DST curve: alpha1 held at {al1:.4g}, varphi1 fitted")
    elif not dst_ok:
        messages.append("stage 3: no DST curve (rate saturating at high stress): eta_B kept from "
                        "the start material and held in stage 4")
    m = dataclasses.replace(m, varphi1=v1, alpha1=al1, varphi2=v2,
                            alpha2=al2 if v2 > 0 else m.alpha2)
    stages = {"1": stage1, "2": stage2, "3": {
        "phi": phd, "gdot_dst": g, "stress_range": [feats[i].dst_stress for i in dst_ok],
        "varphi1": v1, "alpha1": al1, "varphi2": v2, "alpha2": m.alpha2,
        "tau_star_first": m.tau_star, "curves": dst_ok, "kinds": [f.kind for f in feats],
        "top_slopes": [f.top_slope for f in feats],
        "material": m}}                     # the set after stages 1-3 (the stage plots' values)

    # ---------------------------------------------------------------- stage 4
    free_list = [p for p in DEFAULT_FREE if p not in fixed and not (
        p in ("varphi1", "alpha1") and not dst_ok or p == "alpha1" and (
            len(dst_ok) < 2 or etaB_terms == 2 and len(dst_ok) < 3))]
    if etaB_terms == 2 and m.varphi2 > 0 and "varphi2" not in fixed and len(dst_ok) >= 2:
        free_list.append("varphi2")
    for p in free_extra + (["eta0"] if estimate_eta0 else []):
        if p not in free_list and p not in fixed:
            free_list.append(p)
    if m.a0 == m.a_inf and "a_inf" in free_list:
        m = dataclasses.replace(m, a_inf=m.a0 * (1 + 1e-6))
    if stages_only:
        return _finish(data, m, base, [], free_list, np.zeros(data.stress.size, bool), stages,
                       messages, n_eval, t0, confidence, None, None, name, citation, model,
                       fixed=fixed)
    P = _Params(m, free_list, phi_max)

    def resid(theta, sel=slice(None)):
        return logeta[sel] - model(P.material(theta), sel)["log10_viscosity"]

    x_scale = np.where(np.char.startswith(np.array(P.names), "ln_"), 1.0, 0.01)
    x_scale[np.isin(P.names, ["alpha1", "alpha2"])] = 1.0
    box = dict(bounds=(P.lo, P.hi), x_scale=x_scale, method="trf", max_nfev=100)

    def mad(r):                                      # robust standard deviation
        return 1.4826 * float(np.median(np.abs(r - np.median(r))))

    try:
        r1 = least_squares(resid, P.theta(m), loss="soft_l1", f_scale=0.1, xtol=1e-8, ftol=1e-9,
                           **box)
        fs = f_scale if f_scale is not None else max(3 * mad(r1.fun), 1e-3)
        r2 = least_squares(resid, r1.x, loss="soft_l1", f_scale=fs, xtol=1e-10, ftol=1e-11, **box)
        outlier = np.abs(r2.fun - np.median(r2.fun)) > 4 * max(mad(r2.fun), 1e-12)
        r3 = least_squares(lambda th: resid(th, ~outlier), r2.x, xtol=1e-10, ftol=1e-11, **box)
    except (ValueError, FloatingPointError) as exc:
        raise RuntimeError(f"stage 4 failed: {exc}") from None
    if r3.status < 0:
        raise RuntimeError(f"stage 4 failed: {r3.message}")
    if r3.status == 0:
        messages.append(f"stage 4 stopped at its evaluation limit ({r3.nfev} in the polish; "
                        f"optimality {r3.optimality:.2g}): the optimum may not be reached")
    stages["4"] = {"soft_l1_f_scale": fs, "outliers": int(outlier.sum()),
                   "nfev": int(r1.nfev + r2.nfev + r3.nfev), "message": r3.message}
    return _finish(data, P.material(r3.x), base, P, free_list, outlier, stages, messages, n_eval,
                   t0, confidence, r3, resid, name, citation, model,
                   profile=profile and r3.status > 0,       # no profile around a non-optimum
                   fixed=fixed)


def central_jacobian(fun, theta, lo, hi, h=1e-6, *, relative=True, columns=None):
    """d fun/d theta by central differences within [lo, hi] over the first ``columns`` (default
    all) parameters, step h (times max(1, |theta_k|) if ``relative``); shared by the steady and
    the relaxation fits."""
    f0 = fun(theta)
    J = np.empty((f0.size, theta.size if columns is None else columns))
    for k in range(J.shape[1]):
        step = h * max(1.0, abs(theta[k])) if relative else h
        a, b = theta.copy(), theta.copy()
        a[k] = max(theta[k] - step, lo[k])
        b[k] = min(theta[k] + step, hi[k])
        J[:, k] = (fun(b) - fun(a)) / (b[k] - a[k])
    return J


def _finish(data, m, base, P, free_list, outlier, stages, messages, n_eval, t0, confidence, res,
            resid, name, citation, model, profile=False, fixed=()):
    """Intervals, correlations, flags, the fitted Material."""
    final = dataclasses.replace(m, name=name, citation=citation or
                                f"fit of Baumgarten & Kamrin's model to {data.n_curves} measured "
                                f"flow curves, starting from {base.name}",
                                notes="fitted by rheology.fit (stages 1-4 of the Supplement); "
                                      "mu_c held unless freed; eta0 " + (
                                          "estimated from the data" if "eta0" in free_list
                                          else "given"))
    final = final.replace()       # validate
    st = model(final)
    r_all = np.log10(data.viscosity) - st["log10_viscosity"]
    inl = ~outlier
    sigma = float(np.sqrt(np.sum(r_all[inl] ** 2) / max(int(inl.sum()) - len(free_list), 1)))
    params: list[ParameterEstimate] = []
    names_corr, corr, converged = [], np.zeros((0, 0)), True
    if P:
        theta = res.x
        J = central_jacobian(lambda th: resid(th, inl), theta, P.lo, P.hi)
        L = central_jacobian(P.psi, theta, P.lo - 1, P.hi + 1, h=1e-7)
        psi, span = P.psi(theta), P.hi - P.lo
        dof = max(int(inl.sum()) - len(theta), 1)
        ssq = float(np.sum(res.fun ** 2))
        tq, sd, corr, active, degen = interval_statistics(J, theta, P.lo, P.hi, ssq / dof, dof,
                                                          confidence, L)
        names_corr, converged = list(free_list), res.status > 0
        prof = {p: _profile(data, final, free_list, p, psi[k], sd[k], tq, ssq / dof, ssq, inl,
                            P.phi_max, model)
                for k, p in enumerate(free_list) if profile and p in ("phi_j", "phi_c")}
        for k, p in enumerate(free_list):
            val, at, bound = float(getattr(final, p)), None, ""
            if active[k]:
                at_low = theta[k] - P.lo[k] < 1e-7 * span[k]
                physical = P.physical_lo[k] if at_low else P.physical_hi[k]
                at = (at_low, ("at a limit of the law (" + {
                    "a_inf": "a_inf = a0", "Delta": "Delta at 0 or 1"}.get(p, f"{p} = 0") + ")"
                    if physical else f"at the fitter's {'lower' if at_low else 'upper'} search "
                    f"bound {val:.4g}, not a physical limit") + ": one-sided interval")
                bound = "law" if physical else "search"
            partners = [q for j, q in enumerate(free_list)
                        if j != k and abs(corr[k, j]) > CORR_FLAG and not active[j]
                        and {p, q} not in _PIVOT_PAIRS and not active[k]]
            # a symmetric Jacobian interval may reach past the physical range (phi_c's to -0.007
            # on two fractions): reported within 0 < phi_c < phi_j < 1, 0 <= Delta <= 1, alpha >= 0
            top = final.phi_j if p == "phi_c" else 1.0 if p in ("phi_j", "Delta") else np.inf
            params.append(judged_estimate(
                p, val, psi[k], sd[k], tq, STAGE_OF[p], log=SCALE[p] == "log",
                degenerate=bool(degen[k]), partners=partners, at=at, bound=bound,
                width=(np.log(2.0) if SCALE[p] == "log" else 0.02 if p.startswith("phi") else
                       1.0 if p.startswith("alpha") else 0.2), clip=(0.0, top),
                converged=bool(converged), interval=prof.get(p), messages=messages))
        stages.setdefault("4", {})["sigma_log10"] = sigma
    else:
        params += [ParameterEstimate(p, float(getattr(final, p)), float("nan"), float("nan"),
                                     float("nan"), "none", STAGE_OF[p], "stages 1-3")
                   for p in free_list]
    for p in [p for p in SCALE if p not in free_list]:
        v = float(getattr(final, p))
        reason = ("held at the given value" if p in fixed else "held (not fitted by default)"
                  if p in OPTIONAL_FREE else "held (no data for it)")
        params.append(ParameterEstimate(p, v, v, v, 0.0, "fixed", "fixed", "fixed", reason))
    out = FitResult(material=final, parameters=params, correlation=(names_corr, corr),
                    stages=stages, residual_log10=r_all, outlier=outlier,
                    model_viscosity=st["viscosity"], model_rate=st["shear_rate"],
                    sigma_log10=sigma, n_evaluations=n_eval[0],
                    seconds=time.perf_counter() - t0, messages=[x for x in messages if x],
                    confidence=confidence, converged=bool(converged))
    if P:
        out.problems = assess(out, eta0_estimated=stages["1"].get("eta0_estimated", False))
    return out


def judged_estimate(name: str, value: float, centre: float, sd: float, tq: float, stage: str, *,
                    log: bool, degenerate: bool, partners, width: float = np.inf,
                    clip=(-np.inf, np.inf), at=None, bound: str = "", converged: bool = True,
                    interval=None, extra=(), messages=None) -> ParameterEstimate:
    """One fitted parameter's interval and flags (module docstring), shared by the steady and the
    relaxation fits.

    ``centre``, ``sd``: estimate and standard deviation in the reporting coordinate (ln x if
    ``log``), ``tq`` the Student-t quantile; ``interval``: (lower, upper) in that coordinate from
    elsewhere (profile likelihood) in place of centre +- tq sd; ``width``: the widest
    identifiable half-width tq sd; ``clip``: the physical range of a linear coordinate; ``at``:
    (at the lower bound, reason) when on a bound (``bound``: "law" or "search"), the interval
    then one-sided; ``partners``: the parameters correlated beyond :data:`CORR_FLAG`; ``extra``:
    the causes named when it is unidentifiable. ``messages`` gets the sentence of an
    unidentifiable parameter.
    """
    flat = interval is None and (degenerate or not np.isfinite(sd)
                                 or sd <= 1e-12 * max(1.0, abs(centre)))
    lo, hi = interval or ((np.nan, np.nan) if flat else (centre - tq * sd, centre + tq * sd))
    lo, hi = log_interval(lo, hi) if log else (float(np.maximum(lo, clip[0])),
                                               float(np.minimum(hi, clip[1])))
    why = []
    if at is not None:
        why.append(at[1])
        lo, hi = (value, hi) if at[0] else (lo, value)
    wide = not flat and tq * sd > width
    unbounded = not flat and not (np.isfinite(lo) and np.isfinite(hi))
    unident = bool(degenerate or wide or partners or flat or unbounded)
    why += [w for w, on in (
        ("no curvature of the misfit along it", degenerate),
        ("interval wider than " + ("a factor 2" if log else "the identifiability width"), wide),
        (f"correlation > {CORR_FLAG} with " + ", ".join(partners), partners),
        ("interval " + ("undefined" if flat else "unbounded") + " (null)", flat or unbounded),
        *((w, unident) for w in extra),
        ("the optimiser stopped at its evaluation limit", not converged)) if on]
    note = "; ".join(why)
    if unident and messages is not None:
        messages.append(f"{name} is not identified by these data ({note})")
    return ParameterEstimate(
        name, value, *(float(x) if np.isfinite(x) else np.nan for x in (lo, hi, sd)),
        "jacobian" if interval is None else "profile", stage, note=note, at_bound=at is not None,
        unidentifiable=unident, converged=converged, bound=bound)


def paper_span() -> dict[str, tuple[float, float]]:
    """The range of a0, a_inf and phi_j - phi_c over the paper's sets (:data:`PAPER_SETS`)."""
    ms = [get_material(n) for n in PAPER_SETS]
    return {k: (min(f(m) for m in ms), max(f(m) for m in ms)) for k, f in (
        ("a0", lambda m: m.a0), ("a_inf", lambda m: m.a_inf),
        ("phi_j - phi_c", lambda m: m.phi_j - m.phi_c))}


def assess(res: FitResult, eta0_estimated: bool = False) -> list[str]:
    """What makes a fit's result unphysical: one sentence each, naming the parameter, its value,
    why, and what to do (empty when nothing is).

    Checked: phi_j - phi_c wider than :data:`PLAUSIBLE_FACTOR` times the widest gap of the paper's
    sets (phi_c far below phi_j's neighbourhood); a0 or a_inf outside the paper's span widened
    by that factor each way (:func:`paper_span`); a parameter ended on a search bound (not a
    limit of the law); the optimiser's evaluation limit hit; an estimated eta0 not identified.
    """
    m, span, F = res.material, paper_span(), PLAUSIBLE_FACTOR
    out = []
    gap = m.phi_j - m.phi_c
    top = F * span["phi_j - phi_c"][1]
    if gap > top:
        out.append(f"phi_c = {m.phi_c:.4g} lies {gap:.3g} below phi_j = {m.phi_j:.4g}, more than "
                   f"{top:.3g} ({F:g}x the widest gap of the paper's sets): these curves do not "
                   "place phi_c (add curves that reach a high-stress plateau or thicken "
                   "discontinuously, or hold it with --set phi_c=VALUE)")
    for p in ("a0", "a_inf"):
        lo, hi = span[p][0] / F, span[p][1] * F
        v = getattr(m, p)
        if not lo <= v <= hi:
            out.append(f"{p} = {v:.4g} is outside [{lo:.3g}, {hi:.3g}] (the paper's sets span "
                       f"{span[p][0]:g}-{span[p][1]:g}, widened {F:g}x): it scales the viscosity "
                       "with mu_c and eta0 (Eqs. 24-25), so check those held or estimated values "
                       "(--set eta0=VALUE with the liquid's measured viscosity)")
    for q in res.parameters:
        if q.at_bound and q.bound == "search":
            out.append(f"{q.name} = {q.value:.4g} ended on the fitter's search bound, so the bound "
                       f"and not the data sets it: hold it with --set {q.name}=VALUE, or hold or "
                       "free the parameters it trades with")
    if not res.converged:
        out.append("the global fit stopped at its evaluation limit before converging: its "
                   "values are not an optimum (check the held parameters and the residuals)")
    if eta0_estimated:
        e = res.parameter("eta0")
        if e.unidentifiable:
            out.append(f"eta0 = {e.value:.4g} Pa s, estimated from the low-stress plateaus, is "
                       f"not identified by these curves ({e.note}): give the suspending liquid's "
                       "viscosity with --set eta0=VALUE (measured on the liquid alone), or add "
                       "curves at lower phi")
    return out


def _profile(data, best, free_list, p, value, sd, tq, s2, ssq_best, inl, phi_max, model):
    """Profile-likelihood interval of phi_j or phi_c: refit the others at fixed values and find
    where the inlier sum of squares reaches ssq_best + s2 tq^2 (secant on its square root)."""
    others = [q for q in free_list if q != p]
    logeta = np.log10(data.viscosity)[inl]

    def excess(v):                                 # sqrt of the sum of squares' rise / s2
        if p == "phi_j" and (v <= phi_max + 1e-6 or v <= (
                best.phi_c if "phi_c" not in free_list else 0)) or p == "phi_c" and not (
                0 < v < best.phi_j - 1e-5):
            return np.inf
        try:
            start = dataclasses.replace(best, **{p: v})
            if p == "phi_j" and start.phi_c >= v:
                start = dataclasses.replace(start, phi_c=v - (best.phi_j - best.phi_c))
            Q = _Params(start, others, phi_max)
            r = least_squares(lambda t: logeta - model(Q.material(t), inl)["log10_viscosity"],
                              Q.theta(start), bounds=(Q.lo, Q.hi), method="trf", xtol=1e-8,
                              ftol=1e-9, max_nfev=40)
        except (ValueError, RuntimeError):
            return np.inf
        return float(np.sqrt(max(np.sum(r.fun ** 2) - ssq_best, 0.0) / s2))

    ends = []
    for side in (-1.0, 1.0):
        h = max(tq * sd, 1e-5)
        e = excess(value + side * h)
        for _ in range(3):
            if not (np.isfinite(e) and e < tq):
                break
            h *= 2.0
            e = excess(value + side * h)
        if not np.isfinite(e):                     # a bound: bisect towards it
            lo_h, hi_h = 0.0, h
            for _ in range(6):
                mid = 0.5 * (lo_h + hi_h)
                em = excess(value + side * mid)
                lo_h, hi_h = (mid, hi_h) if np.isfinite(em) and em < tq else (lo_h, mid)
            ends.append(value + side * hi_h)
            continue
        if e < tq:
            return None
        h1 = h * tq / max(e, 1e-12)                # sqrt(excess) ~ linear in the offset
        if abs(e / tq - 1) > 0.15:                 # far from the target: one secant step
            e1 = excess(value + side * h1)
            if np.isfinite(e1) and abs(e1 - e) > 1e-12:
                h1 = h1 + (tq - e1) * (h - h1) / (e - e1)
        ends.append(value + side * h1)
    return (min(ends), max(ends))


# ============================================================================ synthetic data
def synthetic_curves(m: Material, phis, *, stress_range=None, points: int = 30,
                     noise: float = 0.03, seed: int = 0, artefacts: bool = True) -> dict:
    """Synthetic measured flow curves from the model, as a rheometer would report them.

    Points at log-spaced MIXTURE stresses (default ``1e-2 tau* .. 1e3 tau*``, as far as a real
    instrument spans around the onset); the rate gets log-normal noise of standard deviation
    ``noise``. Artefacts (``artefacts=True``): the first two points below the torque floor
    (negative rate and viscosity), one repeated reading, a blank cell, and wall slip on the top
    two points of the densest curve (apparent viscosity halved).

    Returns
    -------
    dict with ``curves`` (list of dicts name/stress/rate/status for
    :func:`rheology.data.write_rheocompass`) and ``phi`` (one per curve).
    """
    rng = np.random.default_rng(seed)
    lo, hi = stress_range or (1e-2 * m.tau_star, 1e3 * m.tau_star)
    s = np.logspace(np.log10(lo), np.log10(hi), points)
    curves = []
    phis = [float(p) for p in phis]
    for i, ph in enumerate(phis):
        st = mixture_steady_state(s, ph, m)
        rate = st["shear_rate"] * np.exp(noise * rng.standard_normal(points))
        stress = s.copy()
        status = ["Dy_auto"] * points
        if artefacts:
            rate[:2] = -np.abs(rate[:2]) * 1.5
            status[0] = status[1] = "Dy_auto,ME-,TruStrain"
            k = points // 2
            stress = np.insert(stress, k, stress[k])
            rate = np.insert(rate, k, rate[k] * 1.01)
            status.insert(k, "Dy_auto")
            rate[k + 3] = np.nan
            if i == int(np.argmax(phis)):
                rate[-2:] *= 2.0
        curves.append({"name": "Viscosity curve 1", "stress": stress, "rate": rate,
                       "status": status})
    return {"curves": curves, "phi": phis}


def synthetic_table(m: Material, phis, **kw):
    """:func:`synthetic_curves` as the tidy table of :func:`rheology.data.read_flow_curves`
    (through the same cleaning as a file)."""
    syn = synthetic_curves(m, phis, **kw)
    frames = []
    for c, ph in zip(syn["curves"], syn["phi"]):
        s, r = c["stress"], c["rate"]
        with np.errstate(invalid="ignore", divide="ignore"):
            v = s / r
        n = np.arange(1.0, s.size + 1)
        cur = Curve("synthetic", "Viscosity curve 1", n, n * 6, r, s, v, None,
                    np.array(["ME-" in x for x in c["status"]]))
        frames.append(curve_table(cur, ph, source=f"synthetic_phi_{ph:.4f}"))
    return pd.concat(frames, ignore_index=True)


def recovery_errors(fit: FitResult, truth: Material, phis) -> dict[str, float]:
    """Errors of a fit against the true material: absolute for phi_j, phi_c; relative for a0,
    a_inf, tau*; worst relative gdot_DST over the data's phi in [phi_c, phi_j) of both."""
    m = fit.material
    out = {"phi_j": abs(m.phi_j - truth.phi_j), "phi_c": abs(m.phi_c - truth.phi_c),
           "a0": abs(m.a0 / truth.a0 - 1), "a_inf": abs(m.a_inf / truth.a_inf - 1),
           "tau_star": abs(m.tau_star / truth.tau_star - 1)}
    dst = [p for p in phis if max(truth.phi_c, m.phi_c) <= p < min(truth.phi_j, m.phi_j)]
    out["gdot_dst"] = (max(abs(float(gdot_dst(p, m)) / float(gdot_dst(p, truth)) - 1) for p in dst)
                       if dst else float("nan"))
    return out
