"""Steady simple shear: Eqs. (1)-(2), (13), (20), (24)-(25), (33), for a Material.

The steady state (df/dt = 0 in Table 8, phi = phi_eq) is parametrised by the granular shear stress
``taubar``, for which it is unique: with gdot = gdot_cs(taubar, f) the critical-state rate,
``g(f) = f (H + S(f)) - H f_m`` is strictly increasing on [0, min(f_m, f_jam)) with g(0) <= 0
(H depends on taubar only; S = 1 + (taubar/eta_B + xi_eps)/gdot grows with f because the granular
viscosity does, given a_inf >= a0). One bracketed root per stress, solved for all stresses at once.

Under an imposed shear rate or mixture stress there may be 0, 1 or 2+ steady states (S-shaped
curves, DST). :func:`steady_states_rate` and :func:`steady_states_mixture_stress` trace the unique
stress-parametrised curve, bracket every crossing of the target and refine it, and mark each branch
stable when the control variable increases with taubar there (the rigid-rheometer limit G -> inf:
``d(df/dt)/df = (Phi_f / Gamma_tau) d(gdot)/d(taubar)`` with Phi_f < 0, Gamma_tau > 0).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import pandas as pd
from scipy.optimize import elementwise, minimize_scalar

from . import laws
from runkit.params import check_nonnegative, check_positive, check_range
from .materials import Material, get_material
from .structure import eta_B

_TOL = dict(xatol=1e-300, xrtol=4e-16, fatol=0.0, frtol=0.0)
#: Largest granular shear stress of a steady state, in units of tau* (H <= 1e150).
TAUBAR_MAX_FACTOR = 1e100
#: Smallest representable steady shear rate [1/s] (above the subnormal range).
RATE_MIN = 1e-300


def below_jamming(phi, m: Material, name: str = "phi") -> np.ndarray:
    """``phi`` as a float array in (0, phi_j) of ``m``: the one check of a volume fraction that
    flows; :class:`runkit.params.OutOfRange` naming ``name`` else."""
    return check_range(name, phi, 0.0, m.phi_j, lo_closed=False, hi_closed=False,
                       note=f"steady flow needs phi below phi_j = {m.phi_j} of {m.name}")


# ------------------------------------------------------------------ Eqs. (1), (2), (24), (25)
def granular_viscosity(phi, f, m: Material | str) -> np.ndarray:
    """Granular part of Eq. (1): taubar/(eta0 gdot) = 2 mu (a phi/y)^2 + 5/2 phi^2/y [-].

    y = phi_m(f) - phi; ``inf`` where phi >= phi_m(f) (jammed). mu is the critical-state friction
    (mu_c unless mu_2 != mu_c).
    """
    m = get_material(m)
    phi, y, a = _gap(phi, f, m)
    return np.where(y > 0, _eta_g(phi, y, a, m), np.inf)


def relative_viscosity(phi, f, m: Material | str) -> np.ndarray:
    """Eq. (1): eta_r = tau/(eta0 gdot) = 1 + 5/2 phi phi_m/(phi_m - phi) + 2 mu_c (a phi/(phi_m - phi))^2."""
    eta_g = granular_viscosity(phi, f, m)                 # validates phi and f
    return 1.0 + 2.5 * np.asarray(phi, dtype=float) + eta_g


def normal_viscosity(phi, f, m: Material | str) -> np.ndarray:
    """Eq. (2): eta_n = p/(eta0 gdot) = 2 (a phi/(phi_m - phi))^2 [-]; ``inf`` when jammed."""
    phi, y, a = _gap(phi, f, get_material(m))
    with np.errstate(divide="ignore"):
        return np.where(y > 0, 2 * (a * phi / np.where(y > 0, y, 1.0)) ** 2, np.inf)


def _gap(phi, f, m: Material) -> tuple:
    """(phi, y = phi_m(f) - phi, a(f)) with phi in (0, phi_j) and f in [0, 1] checked."""
    phi = below_jamming(phi, m)
    f = check_range("f", f, 0.0, 1.0)
    return phi, laws.phi_m(f, m.phi_c, m.phi_j) - phi, laws.dilatancy_a(f, m.a0, m.a_inf)


def viscosity_low_limit(phi, m: Material | str) -> np.ndarray:
    """Eq. (24): eta_r as f -> 0 (phi_m = phi_j, a = a0), the low-stress Newtonian plateau [-]."""
    return relative_viscosity(phi, 0.0, m)


def viscosity_high_limit(phi, m: Material | str) -> np.ndarray:
    """Eq. (25): eta_r as f -> 1 (phi_m = phi_c, a = a_inf) [-]; ``inf`` for phi >= phi_c."""
    return relative_viscosity(phi, 1.0, m)


def critical_shear_rate(taubar, phi, f, m: Material | str) -> np.ndarray:
    """Plastic shear rate at the critical state for granular stress taubar [1/s] (Eq. 35 with inertia).

    Multiplied through by (phi_m - phi)^2 it is continuous through jamming and 0 for
    phi >= phi_m(f). This is the algebraic relation of the 0-D (rheometer) model.
    """
    m = get_material(m)
    taubar = check_nonnegative("taubar", taubar)
    phi = check_range("phi", phi, 0.0, 1.0, lo_closed=False, hi_closed=False)
    f = check_range("f", f, 0.0, 1.0)
    y = np.maximum(laws.phi_m(f, m.phi_c, m.phi_j) - phi, 0.0)
    return laws.critical_shear_rate(taubar, phi, y, laws.dilatancy_a(f, m.a0, m.a_inf), m.mu_c,
                                    m.mu2, m.b, m.eta0, m.d, m.rho_s or 0.0)


# ------------------------------------------------------------------ steady states
@dataclass(frozen=True)
class SteadyFlow:
    """Steady simple-shear states, one entry per point (numpy arrays of equal shape).

    Attributes
    ----------
    phi : volume fraction [-]
    taubar : granular shear stress [Pa]
    shear_stress : mixture shear stress tau = taubar + eta0 (1 + 5/2 phi) gdot [Pa]
    shear_rate : shear rate gdot [1/s] (0 when jammed)
    f : structure [-]
    pressure : granular pressure [Pa] (Eq. 2; taubar/mu_c in the jammed limit)
    viscosity : mixture viscosity tau/gdot [Pa s] (inf when jammed)
    jammed : True where no flowing steady state exists at this stress (only if eta_B = inf)
    index : position of the imposed value in the (flattened, broadcast) input, branches only
    branch : 0, 1, ... in order of increasing taubar among the states of one input, branches only
    stable : stable under the imposed control in the rigid-rheometer limit, branches only
    """

    phi: np.ndarray
    taubar: np.ndarray
    shear_stress: np.ndarray
    shear_rate: np.ndarray
    f: np.ndarray
    pressure: np.ndarray
    viscosity: np.ndarray
    jammed: np.ndarray
    index: np.ndarray | None = None
    branch: np.ndarray | None = None
    stable: np.ndarray | None = None

    def to_frame(self):
        """A pandas DataFrame with unit-suffixed columns."""
        names = {"phi": "phi", "taubar": "granular_shear_stress_Pa", "shear_stress":
                 "shear_stress_Pa", "shear_rate": "shear_rate_per_s", "f": "f",
                 "pressure": "granular_pressure_Pa", "viscosity": "viscosity_Pa_s",
                 "jammed": "jammed", "index": "index", "branch": "branch", "stable": "stable"}
        return pd.DataFrame({names[k.name]: np.ravel(getattr(self, k.name)) for k in fields(self)
                             if getattr(self, k.name) is not None})


def steady_residual(f, y, df, taubar, phi, H, k, m: Material):
    """y^2 [f (H + S) - H f_m] for structure f, gap y = phi_m(f) - phi and df = f - f_m.

    Smooth through jamming and increasing in f, so its root is unique. f, y and df are all passed
    because each must be formed without cancellation by the caller (see steady_state_stress):
    with H up to ~1e30 at extreme stress, H df needs df exact, not f - f_m of two close numbers.
    """
    a = laws.dilatancy_a(f, m.a0, m.a_inf)
    mu = laws.critical_friction(phi, y, a, m.mu_c, m.mu2, m.b)
    ap2 = (a * phi) ** 2
    A = mu * ap2 * m.d ** 2 * (m.rho_s or 0.0)
    B = m.eta0 * (2.0 * mu * ap2 + 2.5 * phi * phi * y)
    y2_over_gdot = (B + np.sqrt(B * B + 4.0 * A * taubar * y * y)) / (2.0 * taubar)
    return (H * df + f) * y * y + f * k * y2_over_gdot


def _state(taubar, phi, f, y, jammed, m: Material) -> SteadyFlow:
    """Steady state from the structure f and its jamming gap y = phi_m(f) - phi >= 0 (both exact)."""
    a = laws.dilatancy_a(f, m.a0, m.a_inf)
    rho_s = m.rho_s or 0.0
    gdot = np.where(jammed, 0.0, laws.critical_shear_rate(taubar, phi, y, a, m.mu_c, m.mu2, m.b,
                                                          m.eta0, m.d, rho_s))
    p = np.where(jammed | (gdot <= 0),
                 taubar / laws.critical_friction(phi, y, a, m.mu_c, m.mu2, m.b),
                 laws.critical_pressure(gdot, phi, y, a, m.eta0, m.d, rho_s))
    tau = taubar + m.eta0 * (1.0 + 2.5 * phi) * gdot
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        visc = np.where(gdot > 0, tau / np.where(gdot > 0, gdot, 1.0), np.inf)
        zero_shear = m.eta0 * (1.0 + 2.5 * phi + _eta_g(phi, y, a, m))
    visc = np.where(taubar <= 0, zero_shear, visc)
    return SteadyFlow(phi=phi, taubar=taubar, shear_stress=tau, shear_rate=gdot, f=f, pressure=p,
                      viscosity=visc, jammed=jammed)


def _eta_g(phi, y, a, m: Material):
    """Granular part of Eq. (1) at gap y > 0."""
    y = np.maximum(y, laws.TINY)
    mu = laws.critical_friction(phi, y, a, m.mu_c, m.mu2, m.b)
    return 2 * mu * (a * phi / y) ** 2 + 2.5 * phi ** 2 / y


def steady_state_stress(taubar, phi, m: Material | str) -> SteadyFlow:
    """The unique steady state at imposed granular shear stress, for any number of points.

    Parameters
    ----------
    taubar : array_like
        Granular shear stress [Pa], >= 0 (broadcast against ``phi``).
    phi : array_like
        Volume fraction, 0 < phi < phi_j.
    m : Material or str
        A parameter set or its registry name (see rheology.get_material).

    Returns
    -------
    SteadyFlow
        Satisfies Eq. (13) to ~1e-13 relative. ``jammed`` is True (gdot = 0, f = f_jam) only when
        eta_B = inf and xi_eps = 0 and H f_m/(H + 1) >= f_jam: the flowing branch has ended.

    Raises
    ------
    ValueError
        taubar < 0, > 1e100 tau*, or not finite; phi outside (0, phi_j); or a steady state that
        is not representable in double precision (a shear rate below 1e-300 1/s or overflowing,
        e.g. eta0 = 1e300 Pa s), naming taubar, phi and eta0.
    """
    m = get_material(m)
    taubar = check_range("taubar", taubar, 0.0, TAUBAR_MAX_FACTOR * m.tau_star,
                         note=f"{TAUBAR_MAX_FACTOR:.0e} tau* of {m.name}: beyond, the hardening "
                              f"H = (taubar/tau*)^(3/2) leaves double precision")
    return _steady(taubar, below_jamming(phi, m), m)


@np.errstate(all="ignore")                   # every result is checked: _check_representable
def _steady(taubar, phi, m: Material) -> SteadyFlow:
    """:func:`steady_state_stress` at checked arrays taubar and phi."""
    taubar, phi = (x.astype(float).copy() for x in np.broadcast_arrays(taubar, phi))
    dphi = m.phi_j - m.phi_c
    fm = laws.f_max(phi, m.phi_c, m.phi_j, m.Delta)
    fjam = (m.phi_j - phi) / dphi
    H = laws.hardening(taubar, m.tau_star)
    k = taubar * laws.inv_eta_B(phi, m.phi_j, m.varphi1, m.alpha1, m.varphi2, m.alpha2) + m.xi_eps
    f, y = np.zeros_like(taubar), m.phi_j - phi              # f = 0 (taubar = 0 or f_m = 0)

    no_decay = (k <= 0) & (taubar > 0)                       # S = 1: closed form f = H f_m/(H + 1)
    f_closed = np.minimum(H * fm / (H + 1.0), fjam)
    jammed = no_decay & (f_closed >= fjam)
    f = np.where(no_decay, f_closed, f)
    y = np.where(no_decay, dphi * (fjam - f_closed), y)

    solve = (k > 0) & (taubar > 0) & (fm > 0)
    if np.any(solve):
        idx = np.flatnonzero(solve.ravel())
        t, ph, h, fms, ks, fj = (x.ravel()[idx] for x in (taubar, phi, H, fm, k, fjam))
        y0 = m.phi_j - ph                                    # gap at f = 0
        fhi = np.minimum(fms, fj)                            # the root lies in [0, f_hi)
        yhi = np.where(fms < fj, dphi * (fj - fms), 0.0)     # gap at f_hi (exactly 0 if jammed)
        fhalf = 0.5 * fhi
        # Lower half: solve in f (y = y0 - f dphi, f - f_m = f - f_m, no cancellation). Upper
        # half: solve in w = f_hi - f (f - f_m = (f_hi - f_m) - w, y = y_hi + w dphi: sums of
        # like-signed terms). f, y and f - f_m then keep full relative precision everywhere, at
        # low stress and 1e-12 from jamming alike.
        lower = steady_residual(fhalf, y0 - fhalf * dphi, fhalf - fms, t, ph, h, ks, m) > 0
        # per half: the unknown x's (f, y, f - f_m), the residual's sign, the bracket's width
        halves = ((lower, lambda x, fh, yh, fm_, p_: (x, m.phi_j - p_ - x * dphi, x - fm_), 1.0,
                   fhalf),
                  (~lower, lambda x, fh, yh, fm_, p_: (fh - x, yh + x * dphi, (fh - fm_) - x),
                   -1.0, fhi - fhalf))
        fs, ys = np.empty_like(t), np.empty_like(t)
        for sel, parts, sign, width in halves:
            if not np.any(sel):
                continue
            args = tuple(x[sel] for x in (fhi, yhi, fms, t, ph, h, ks))
            fun = lambda x, fh, yh, fm_, t_, p_, *rest, parts=parts, sign=sign: sign * (
                steady_residual(*parts(x, fh, yh, fm_, p_), t_, p_, *rest, m))
            res = elementwise.find_root(fun, (np.zeros_like(args[0]), width[sel]), args=args,
                                        tolerances=_TOL)
            if not np.all(res.success):
                bad = np.flatnonzero(~res.success)[0]
                raise RuntimeError(f"steady stress-controlled solve failed at taubar = "
                                   f"{args[3][bad]:.6g} Pa, phi = {args[4][bad]:.6g} "
                                   f"(status {res.status[bad]})")
            fs[sel], ys[sel], _ = parts(res.x, *args[:3], args[4])
        f.ravel()[idx], y.ravel()[idx] = fs, ys
    out = _state(taubar, phi, f, y, jammed, m)
    _check_representable(out, m)
    return out


def _check_representable(st: SteadyFlow, m: Material) -> None:
    """ValueError where a flowing steady state is not representable in double precision: a
    shear rate that underflows (below 1e-300 1/s: eta0 huge or the stress tiny) or any
    non-finite rate, stress or pressure (no silent rate 0 / viscosity inf)."""
    flowing = (st.taubar > 0) & ~st.jammed
    with np.errstate(invalid="ignore"):
        bad = flowing & ~((st.shear_rate >= RATE_MIN) & np.isfinite(st.shear_rate)
                          & np.isfinite(st.shear_stress) & np.isfinite(st.pressure)
                          & (st.viscosity > 0) & np.isfinite(st.viscosity))
    if np.any(bad):
        k = np.flatnonzero(np.ravel(bad))[0]
        t, ph, g = (float(np.ravel(x)[k]) for x in (st.taubar, st.phi, st.shear_rate))
        raise ValueError(
            f"taubar = {t:.6g} Pa at phi = {ph:.6g} ({m.name}, eta0 = {m.eta0:.6g} Pa s): the "
            f"steady state is not representable in double precision (shear rate {g:.3g} 1/s); "
            f"valid: steady shear rates in [{RATE_MIN:g}, 1e300] 1/s with finite stresses, i.e. "
            f"taubar/eta0 within about [1e-290, 1e290] 1/s")


def _trace(phi, lo, hi, n, m: Material):
    """The stress-parametrised steady curve on a log grid of taubar between lo and hi (per phi)."""
    s = np.linspace(0.0, 1.0, n)
    taus = np.exp(np.log(lo)[:, None] + (np.log(hi) - np.log(lo))[:, None] * s[None, :])
    return taus, _steady(taus, np.broadcast_to(phi[:, None], taus.shape), m)


def _empty() -> SteadyFlow:
    empty = np.zeros(0)
    return SteadyFlow(*(empty,) * 7, jammed=np.zeros(0, bool), index=np.zeros(0, int),
                      branch=np.zeros(0, int), stable=np.zeros(0, bool))


def _branches(control: str, target, phi, m: Material, points_per_decade: int, hi_factor: float):
    target = check_positive(control, target)
    phi = below_jamming(phi, m)
    points_per_decade = int(check_range("points_per_decade", points_per_decade, 4, 1e5))
    target, phi = (np.ravel(x).astype(float) for x in np.broadcast_arrays(target, phi))
    if target.size == 0:
        return _empty()
    eta_f = m.eta0 * (1.0 + 2.5 * phi)
    eta_lo = m.eta0 * _eta_g(phi, m.phi_j - phi, m.a0, m)
    top = 1e-3 * TAUBAR_MAX_FACTOR * m.tau_star          # room above for the search grid
    if control == "shear_rate":
        check_range("taubar_max_factor", hi_factor, 1.0, 1e-3 * TAUBAR_MAX_FACTOR)
        lo = 0.5 * eta_lo * target                       # gdot(taubar) <= taubar/eta_lo
        hi = np.maximum(hi_factor * m.tau_star, 1e3 * lo)
        value, most = (lambda st: st.shear_rate), float(np.min(top / (0.5 * eta_lo * 1e3)))
    else:
        lo = 0.5 * target / (1.0 + eta_f / eta_lo)       # tau <= taubar (1 + eta_f/eta_lo)
        hi = target                                       # tau > taubar
        value, most = (lambda st: st.shear_stress), top
    check_range(control, target, 0.0, most, lo_closed=False, note=f"steady states are searched "
                f"up to taubar = {TAUBAR_MAX_FACTOR:.0e} tau* of {m.name}")
    decades = (np.log10(hi) - np.log10(lo)).max()          # hi/lo may overflow (1e-300 .. 1)
    n = int(max(64, points_per_decade * decades))
    taus, st = _trace(phi, lo, hi, n, m)
    r = value(st) - target[:, None]
    up = r > 0

    def resid(logt, tg, ph):
        return value(_steady(np.exp(logt), ph, m)) - tg

    # brackets (row, log taubar lo, hi, stable): the sign changes on the grid, plus pairs of
    # states at a fold that falls between grid points (the target within a grid step of an
    # extremum of the curve)
    i, j = np.nonzero(up[:, 1:] != up[:, :-1])
    lt = np.log(taus)
    rows, a, b = list(i), list(lt[i, j]), list(lt[i, j + 1])
    stab = list(~up[i, j])                               # crossing upwards: d(control)/d(taubar) > 0
    d = np.diff(r, axis=1)
    for q, k in zip(*np.nonzero((d[:, :-1] > 0) != (d[:, 1:] > 0))):
        if up[q, k] != up[q, k + 1] or up[q, k + 1] != up[q, k + 2]:
            continue                                     # the grid already brackets these
        sgn = 1.0 if d[q, k] > 0 else -1.0               # a maximum or a minimum of r
        if up[q, k + 1] == (sgn > 0) or abs(r[q, k + 1]) > abs(d[q, k]) + abs(d[q, k + 1]):
            # a maximum above or a minimum below the target, or one out of its reach: a smooth
            # extremum between the samples exceeds the middle one by at most ~1/8 of this sum
            continue
        ext = minimize_scalar(lambda x: -sgn * resid(x, target[q], phi[q]), method="bounded",
                              bounds=(lt[q, k], lt[q, k + 2]), options=dict(xatol=1e-12))
        r_ext = sgn * resid(ext.x, target[q], phi[q])
        if r_ext < -1e-12 * abs(target[q]):
            continue                                     # the fold does not reach the target
        # through the fold: one state on each side; touching it: a double state at the fold
        edges = (lt[q, k], ext.x, lt[q, k + 2]) if r_ext > 0 else (ext.x,) * 3
        rows += [q, q]
        a += edges[:2]
        b += edges[1:]
        stab += [sgn > 0, sgn < 0]                       # rising then falling through a maximum
    if not rows:
        return _empty()
    order = np.lexsort((np.array(a), np.array(rows)))
    i = np.array(rows)[order]
    a, b, stable = np.array(a)[order], np.array(b)[order], np.array(stab, dtype=bool)[order]
    tg, ph = target[i], phi[i]
    x = a.copy()
    open_ = a < b
    if open_.any():
        res = elementwise.find_root(resid, (a[open_], b[open_]), args=(tg[open_], ph[open_]),
                                    tolerances=dict(xatol=1e-13, xrtol=4e-16))
        x[open_] = res.x
    st_root = _steady(np.exp(x), ph, m)
    branch = np.zeros(i.size, dtype=int)
    for q in range(1, i.size):
        branch[q] = branch[q - 1] + 1 if i[q] == i[q - 1] else 0
    return SteadyFlow(**{k.name: getattr(st_root, k.name) for k in fields(st_root)
                         if k.name not in ("index", "branch", "stable")},
                      index=i, branch=branch, stable=stable)


def steady_states_rate(gdot, phi, m: Material | str, *, points_per_decade: int = 40,
                       taubar_max_factor: float = 1e8) -> SteadyFlow:
    """Every steady state at an imposed shear rate, each marked stable or unstable.

    Parameters
    ----------
    gdot : array_like
        Imposed shear rate(s) [1/s], > 0 (broadcast against ``phi``).
    phi : array_like
        Volume fraction(s), 0 < phi < phi_j.
    points_per_decade : int
        Resolution of the taubar grid used to bracket the states.
    taubar_max_factor : float
        The search covers taubar up to this many tau* (beyond, gdot has converged to its
        high-stress limit to ~1e-4).

    Returns
    -------
    SteadyFlow
        One entry per state, with ``index`` (which input), ``branch`` and ``stable``.
    """
    m = get_material(m)
    return _branches("shear_rate", gdot, phi, m, points_per_decade, taubar_max_factor)


def steady_states_mixture_stress(tau, phi, m: Material | str, *,
                                 points_per_decade: int = 400) -> SteadyFlow:
    """Every steady state at an imposed mixture shear stress tau [Pa], marked stable or unstable.

    The mixture stress tau = taubar + eta0 (1 + 5/2 phi) gdot lies within a narrow band above
    taubar, searched on a fine grid; usually a single state.
    """
    m = get_material(m)
    return _branches("shear_stress", tau, phi, m, points_per_decade, 1.0)


# ------------------------------------------------------------------ DST and conversions
def gdot_dst(phi, m: Material | str) -> np.ndarray:
    """Eq. (33): shear rate of DST, the high-stress limit of the steady curve [1/s].

    gdot_DST = (tau*/eta0) (2 mu_c (eta_B/eta0 a(f_m) phi/(phi_j - phi))^2)^(-1/3), valid for
    phi_c <= phi <= phi* (0 if eta_B = inf).
    """
    m = get_material(m)
    phi = check_range("phi", phi, m.phi_c, min(m.phi_star, m.phi_j), hi_closed=m.phi_star < m.phi_j,
                      note=f"DST exists only for phi_c <= phi <= phi* in {m.name}")
    fm = laws.f_max(phi, m.phi_c, m.phi_j, m.Delta)
    a = laws.dilatancy_a(fm, m.a0, m.a_inf)
    with np.errstate(divide="ignore"):
        return (m.tau_star / m.eta0) * (2.0 * m.mu_c * (eta_B(phi, m) / m.eta0 * a * phi
                                                        / (m.phi_j - phi)) ** 2) ** (-1.0 / 3.0)


def phi_from_mass_fraction(phi_w, rho_cs: float, rho_l: float, rho_w: float = 1000.0,
                           lam: float = 0.3, beta: float = 0.1) -> np.ndarray:
    """Eq. (20): volume fraction of swollen starch from the mass fraction phi_W [-].

    Parameters
    ----------
    phi_w : array_like
        Mass fraction m_cs/(m_cs + m_l), in (0, 1).
    rho_cs, rho_l, rho_w : float
        Densities of cornstarch grains, suspending liquid and water [kg/m^3].
    lam, beta : float
        Swelling and pore-space parameters (lambda ~ 0.3, beta ~ 0.1 after Peters et al. 2016).
    """
    phi_w = check_range("phi_w", phi_w, 0.0, 1.0, lo_closed=False, hi_closed=False)
    for name, v in (("rho_cs", rho_cs), ("rho_l", rho_l), ("rho_w", rho_w)):
        check_positive(name, v)
    check_range("beta", beta, 0.0, 1.0, hi_closed=False)
    check_nonnegative("lam", lam)
    return ((1 + lam) * (1 - beta)
            / ((1 - beta) + (1 - phi_w) / phi_w * rho_cs / rho_l + beta * rho_cs / rho_w))


def dst_fold(material, phi: float) -> tuple[float, float] | None:
    """(shear rate [1/s], mixture shear stress [Pa]) of the fold of the steady curve: the largest
    steady shear rate, where DST sets in (above it no steady flow exists under rate control and
    the sample shear-jams); None if the curve of ``phi`` has no fold (no DST). Eqs. (13), (1)
    on the grid of :func:`steady_fold`."""
    fold = steady_fold(material, phi)
    if fold is None:
        return None
    taus, st, g, i = fold
    return float(g[i]), float(st.shear_stress[i])


def steady_fold(material, phi: float):
    """The first fold of the steady curve on a grid of 1201 granular stresses over tau* 1e-4 ..
    1e8 (0.8% steps): ``(taus, steady, rates, i)`` with ``i`` the grid maximum of the shear rate
    (jammed states count as rate 0), or None if the curve of ``phi`` has no fold. Shared by
    :func:`dst_fold` and :func:`rheometer.oscillation.dst_onset_stress` (which refines it)."""
    m = get_material(material)
    taus = m.tau_star * np.logspace(-4, 8, 1201)
    st = steady_state_stress(taus, phi, m)
    g = np.where(st.jammed, 0.0, st.shear_rate)
    k = np.flatnonzero((g[1:-1] >= g[:-2]) & (g[1:-1] > g[2:]))
    if k.size == 0:
        return None
    return taus, st, g, int(k[0]) + 1
