"""The instrument around the 0-D sample: measuring geometries and normalised column names (the
mass fractions of Eq. 20 are :mod:`rheology.sample`'s, the default fractions
:mod:`rheology.materials`').

Measuring geometries (standard conversions, e.g. Macosko, *Rheology* (1994) ch. 5; ISO 3219):

============== =============================================== ===================================
geometry        torque M [N m] and rotation speed Omega [rad/s]  apparent stress and rate shown
============== =============================================== ===================================
cone-plate      M = 2 pi R^3 sigma/3, Omega = gdot tan(alpha)     sigma = 3 M/(2 pi R^3),
                (cone angle alpha, radius R)                     gdot = Omega/tan(alpha)
parallel-plate  M = 2 pi int_0^R sigma(gdot_R r/R) r^2 dr,       sigma_a = 2 M/(pi R^3) (Newtonian
                Omega = gdot_R h/R (radius R, gap h)             assumption), gdot_R = Omega R/h
couette         M = 2 pi R_i^2 L sigma_i,                        sigma_i = M/(2 pi R_i^2 L),
                Omega = gdot_i (R_o^2 - R_i^2)/(2 R_o^2)         gdot_i = 2 Omega R_o^2/(R_o^2 -
                (bob R_i, cup R_o, bob length L)                 R_i^2) (Newtonian, at the bob)
============== =============================================== ===================================

The cone-plate gap is homogeneous, so its apparent values are the sample's. The Couette
conversion is the Newtonian one at the bob; the 0-D sample is taken as homogeneous in the gap
(narrow-gap limit; the wide gap, where DST localises, is ``shear1d annular``'s job). The
parallel plate is not homogeneous: the shear rate grows linearly with radius. For steady flow its
torque integrates the model's local steady state over the plate (:func:`parallel_plate_flow_curve`);
the displayed stress ``sigma_a`` is then not the rim stress, and the Weissenberg-Rabinowitsch
correction ``sigma_R = sigma_a (3 + d ln M/d ln gdot_R)/4`` recovers it wherever each radius is on
one branch of the curve (:func:`weissenberg_rabinowitsch`). For transient and oscillatory tests
the parallel-plate columns use the homogeneous (rim) conversion and say so.

Normalised materials (the Singh sets, Table 1: eta0 = gdot_0 = 1) write normalised column names:
stresses in eta0 gdot_0 (``_Pa`` -> ``_eta0_gdot0``), rates in gdot_0 (``_per_s`` -> ``_gdot0``),
times in 1/gdot_0 (``time_s`` -> ``time_per_gdot0``), viscosities in eta0 (``_Pa_s`` -> ``_eta0``),
frequencies in gdot_0 (``_Hz`` -> ``_gdot0``) and torques in eta0 gdot_0 m^3
(:func:`normalise_columns`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd
from scipy.integrate import cumulative_simpson

import rheology
from runkit import limits as physical
from runkit.limits import Bound, le
from runkit.params import Param, Schema, check_positive

GEOMETRIES = ("cone-plate", "parallel-plate", "couette")
#: Default dimensions: a 50 mm 1 degree cone (CP50-1), a 25 mm plate at 1 mm gap (PP25), a
#: concentric cylinder of 26.66/28.92 mm bob/cup diameter and 40 mm bob length (CC27).
DEFAULTS = dict(cone_angle_deg=1.0, cone_radius=0.025, plate_radius=0.0125, gap=0.001,
                bob_radius=0.01333, cup_radius=0.01446, bob_length=0.040)
#: The cone angle's top and its reason.
CONE_ANGLE_MAX = 10.0
CONE_ANGLE_WHY = ("the cone-plate conversions take the angle small (a shear rate Omega/tan(alpha) "
                  "uniform across the gap); commercial cones are 0.5-4 deg")
#: a length of the instrument: [1e-6, 10] m (runkit.limits, every tier's lengths)
LENGTH = Param(physical.LENGTH_MIN, physical.LENGTH_MAX, unit="m")
_NARROWEST = physical.LENGTH_MIN.value
_RIM = (f"the gap at the rim, R tan(angle), at least {_NARROWEST:g} m: "
        f"{physical.LENGTH_MIN.why}")
_CUP = (f"the cup radius exceeds the bob radius by a gap of at least {_NARROWEST:g} m: "
        f"{physical.LENGTH_MIN.why}")
#: a bound derived from another dimension makes its other bound derived too: a refusal states
#: the whole range at the others (a static top alone would print (-inf, 10])
CONE_ANGLE = Param(Bound(lambda p: math.degrees(math.atan(_NARROWEST / p["radius"])), True,
                         _RIM), le(lambda p: CONE_ANGLE_MAX, CONE_ANGLE_WHY), unit="deg")
CUP_RADIUS = Param(Bound(lambda p: p["bob_radius"] + _NARROWEST, True, _CUP),
                   le(lambda p: physical.LENGTH_MAX.value, physical.LENGTH_MAX.why), unit="m")
LENGTH_MIN, LENGTH_MAX = physical.LENGTH_MIN.value, physical.LENGTH_MAX.value
#: the dimensions of each geometry as :meth:`Geometry.make` takes them, with their defaults
DIMENSIONS = {
    "cone-plate": ({"cone_angle_deg": CONE_ANGLE, "radius": LENGTH},
                   {"cone_angle_deg": DEFAULTS["cone_angle_deg"],
                    "radius": DEFAULTS["cone_radius"]}),
    "parallel-plate": ({"radius": LENGTH, "gap": LENGTH},
                       {"radius": DEFAULTS["plate_radius"], "gap": DEFAULTS["gap"]}),
    "couette": ({"bob_radius": LENGTH, "cup_radius": CUP_RADIUS, "bob_length": LENGTH},
        {k: DEFAULTS[k] for k in ("bob_radius", "cup_radius", "bob_length")})}
_WORDS = {"cone_angle_deg": "cone angle", "bob_radius": "bob radius", "cup_radius": "cup radius",
          "bob_length": "bob length"}
#: Instrument columns.
INSTRUMENT_COLUMNS = ("torque_N_m", "rotation_speed_rad_per_s", "apparent_shear_stress_Pa",
                      "apparent_shear_rate_per_s")


# ------------------------------------------------------------------ geometries
@dataclass(frozen=True)
class Geometry:
    """A measuring geometry.

    Attributes
    ----------
    kind : {"cone-plate", "parallel-plate", "couette"}
    radius : cone or plate radius R [m] (couette: bob radius R_i)
    cone_angle : cone angle alpha [rad] (cone-plate)
    gap : plate gap h [m] (parallel-plate)
    cup_radius : cup radius R_o [m] (couette), > R_i
    length : immersed bob length L [m] (couette)

    Made by :meth:`make`, which checks the dimensions.
    """

    kind: str
    radius: float
    cone_angle: float = 0.0
    gap: float = 0.0
    cup_radius: float = 0.0
    length: float = 0.0

    @classmethod
    def make(cls, kind: str, label=None, **dimensions) -> "Geometry":
        """A geometry from the instrument's words (``cone_angle_deg``, ``radius``, ``gap``,
        ``bob_radius``, ``cup_radius``, ``bob_length``; defaults :data:`DEFAULTS`), its
        dimensions checked once (:data:`DIMENSIONS`: lengths in [1e-6, 10] m, a gap at the rim
        of at least 1e-6 m, the cone angle at most 10 deg); ValueError with the valid range of
        a dimension at the others, naming it by ``label(name)`` (default in words)."""
        if kind not in GEOMETRIES:
            raise ValueError(f"geometry = {kind!r} must be one of {', '.join(GEOMETRIES)}")
        params, defaults = DIMENSIONS[kind]
        d = Schema(params, defaults, label=label or (lambda k: _WORDS.get(k, k)),
                   where=f"geometry {kind}").check(dimensions)
        if kind == "cone-plate":
            return cls(kind, d["radius"], cone_angle=math.radians(d["cone_angle_deg"]))
        if kind == "parallel-plate":
            return cls(kind, d["radius"], gap=d["gap"])
        return cls(kind, d["bob_radius"], cup_radius=d["cup_radius"], length=d["bob_length"])

    def describe(self) -> str:
        if self.kind == "cone-plate":
            return (f"cone-plate R = {self.radius * 1e3:g} mm, angle "
                    f"{math.degrees(self.cone_angle):g} deg")
        if self.kind == "parallel-plate":
            return f"parallel-plate R = {self.radius * 1e3:g} mm, gap {self.gap * 1e3:g} mm"
        return (f"couette bob R_i = {self.radius * 1e3:g} mm, cup R_o = "
                f"{self.cup_radius * 1e3:g} mm, L = {self.length * 1e3:g} mm")

    # the standard conversions (homogeneous sample; parallel plate: Newtonian assumption)
    def stress_factor(self) -> float:
        """sigma = M * factor [1/m^3]: 3/(2 pi R^3), 2/(pi R^3), 1/(2 pi R_i^2 L)."""
        R = self.radius
        if self.kind == "cone-plate":
            return 3.0 / (2.0 * math.pi * R ** 3)
        if self.kind == "parallel-plate":
            return 2.0 / (math.pi * R ** 3)
        return 1.0 / (2.0 * math.pi * R ** 2 * self.length)

    def rate_factor(self) -> float:
        """gdot = Omega * factor [-]: 1/tan(alpha), R/h, 2 R_o^2/(R_o^2 - R_i^2)."""
        if self.kind == "cone-plate":
            return 1.0 / math.tan(self.cone_angle)
        if self.kind == "parallel-plate":
            return self.radius / self.gap
        Ro2, Ri2 = self.cup_radius ** 2, self.radius ** 2
        return 2.0 * Ro2 / (Ro2 - Ri2)

    def torque(self, stress) -> np.ndarray:
        """Torque [N m] of a homogeneous sample at shear stress ``stress`` [Pa]."""
        return np.asarray(stress, dtype=float) / self.stress_factor()

    def rotation_speed(self, rate) -> np.ndarray:
        """Rotation speed [rad/s] for the (rim or bob) shear rate ``rate`` [1/s]."""
        return np.asarray(rate, dtype=float) / self.rate_factor()

    def readings(self, rate, torque) -> np.ndarray:
        """The :data:`INSTRUMENT_COLUMNS` (torque [N m], rotation speed [rad/s], the displayed
        stress [Pa] and rate [1/s]) of ``torque`` at the (rim or bob) shear rate ``rate``
        [1/s]; shape (n, 4)."""
        W = self.rotation_speed(rate)
        return np.column_stack([torque, W, *self.apparent(torque, W)])

    def apparent(self, torque, speed) -> tuple[np.ndarray, np.ndarray]:
        """(stress [Pa], rate [1/s]) the instrument displays for ``torque`` [N m] and ``speed``
        [rad/s] by the standard conversions."""
        return (np.asarray(torque, dtype=float) * self.stress_factor(),
                np.asarray(speed, dtype=float) * self.rate_factor())


def instrument_columns(df: pd.DataFrame, geometry: Geometry, *, stress="shear_stress_Pa",
                       rate="shear_rate_per_s") -> pd.DataFrame:
    """Add :data:`INSTRUMENT_COLUMNS` to a homogeneous-sample table (transients, oscillation
    waveforms, flow curves in cone-plate or couette): torque and speed from the sample's stress
    and rate, then the displayed values from torque and speed. Returns a new DataFrame."""
    out = df.copy()
    out[list(INSTRUMENT_COLUMNS)] = geometry.readings(out[rate].to_numpy(),
                                                      geometry.torque(out[stress].to_numpy()))
    out.attrs.update(df.attrs)
    out.attrs["geometry"] = geometry.describe()
    return out


# ------------------------------------------------------------------ the parallel plate
def rising_branch(material, phi: float, points: int = 2000, tau_range=None):
    """The steady flow curve up to its first fold (where the shear rate stops rising with the
    stress): the states a rate-controlled sample reaches from rest, on which the mixture stress
    is a single-valued, increasing function of the shear rate.

    Returns (SteadyFlow on a log grid of granular stress, fold_reached: bool). ``tau_range``
    [Pa] defaults to 1e-6..1e6 tau*.
    """
    m = rheology.get_material(material)
    lo, hi = tau_range if tau_range is not None else (1e-6 * m.tau_star, 1e6 * m.tau_star)
    taus = np.geomspace(lo, hi, int(points))
    st = rheology.steady_state_stress(taus, phi, m)
    g = np.where(st.jammed, 0.0, st.shear_rate)
    falls = np.flatnonzero(np.diff(g) <= 0)
    n = falls[0] + 1 if falls.size else taus.size
    cut = rheology.steady_state_stress(taus[:n], phi, m)
    return cut, bool(falls.size)


def parallel_plate_flow_curve(material, phi: float, geometry: Geometry | None = None,
                              points: int = 2000) -> pd.DataFrame:
    """Steady flow curve a parallel-plate rheometer measures, beside the true one.

    The shear rate at radius r is gdot_R r/R; each radius carries the model's local steady
    state at its rate, on the rising branch (the state reached from rest under rate control).
    Parametrised by the rim granular stress taubar_R along that branch, the torque is
    ``M = 2 pi R^3/gdot_R^3 I``, ``I = int_0^gdot_R sigma(g) g^2 dg = int sigma d(g^3/3)``,
    computed in taubar (both sigma and g^3/3 are smooth there, also at the fold, where
    sigma(g) has a vertical tangent) by cumulative Simpson on ``points`` log-spaced stresses.
    The instrument displays ``sigma_a = 2 M/(pi R^3) = 4 I/gdot_R^3`` at ``gdot_R``.
    Beyond the fold no steady state exists at the rim under rate control: the curve ends.

    Returns
    -------
    DataFrame
        ``phi, rim_shear_rate_per_s, shear_stress_Pa`` (true: the local curve at the rim rate),
        ``apparent_shear_stress_Pa``, ``corrected_shear_stress_Pa`` (Weissenberg-Rabinowitsch
        on the (M, Omega) data), ``torque_N_m``, ``rotation_speed_rad_per_s``,
        ``granular_shear_stress_Pa`` (rim), ``f`` (rim); attrs: fold_reached, geometry.
    """
    geometry = geometry or Geometry.make("parallel-plate")
    if geometry.kind != "parallel-plate":
        raise ValueError(f"geometry = {geometry.kind!r}: the radial integration is for the "
                         f"parallel plate")
    m = rheology.get_material(material)
    st, fold = rising_branch(m, phi, points)
    g = st.shear_rate
    sigma = st.shear_stress
    keep = g > 0
    g, sigma, taub, f = g[keep], sigma[keep], st.taubar[keep], st.f[keep]
    u = g ** 3 / 3.0
    I = u[0] * sigma[0] * 0.75 + cumulative_simpson(sigma, x=u, initial=0.0)
    # (the first interval [0, g0]: sigma ~ eta g there, int eta g^3 dg = eta g0^4/4 = 3/4 u0 sigma0)
    R = geometry.radius
    M = 2.0 * math.pi * R ** 3 * I / g ** 3
    W = geometry.rotation_speed(g)
    s_a, g_a = geometry.apparent(M, W)
    df = pd.DataFrame({"phi": phi, "rim_shear_rate_per_s": g_a, "shear_stress_Pa": sigma,
                       "apparent_shear_stress_Pa": s_a,
                       "corrected_shear_stress_Pa": weissenberg_rabinowitsch(g_a, M, geometry),
                       "torque_N_m": M, "rotation_speed_rad_per_s": W,
                       "granular_shear_stress_Pa": taub, "f": f})
    df.attrs.update(material=m.name, fold_reached=fold, geometry=geometry.describe())
    return df


def weissenberg_rabinowitsch(rim_rate, torque, geometry: Geometry) -> np.ndarray:
    """Rim shear stress [Pa] from parallel-plate data: sigma_R = M/(2 pi R^3) (3 + n),
    n = d ln M/d ln gdot_R taken from the data (second-order finite differences in log-log, as
    on measured points). Exact where every radius is on one branch of a single-valued curve."""
    g = check_positive("rim shear rate [1/s]", rim_rate)
    M = check_positive("torque [N m]", torque)
    if g.size < 3:
        raise ValueError("the Weissenberg-Rabinowitsch correction needs at least 3 points")
    n = np.gradient(np.log(M), np.log(g))
    return M / (2.0 * math.pi * geometry.radius ** 3) * (3.0 + n)


# ------------------------------------------------------------------ normalised columns
_SUFFIXES = (("_Pa_s", "_eta0"), ("_N_m", "_eta0_gdot0_m3"), ("_rad_per_s", "_rad_gdot0"),
             ("_per_s", "_gdot0"), ("_Pa", "_eta0_gdot0"), ("_Hz", "_gdot0"),
             ("_s", "_per_gdot0"))


def normalised_name(column: str) -> str:
    """The column name in the normalised units of Table 1 (eta0 = gdot_0 = 1)."""
    for old, new in _SUFFIXES:
        if column.endswith(old):
            return column[: -len(old)] + new
    return column


def normalise_columns(df: pd.DataFrame, material) -> pd.DataFrame:
    """``df`` with normalised column names if ``material`` is in normalised units, else ``df``."""
    m = rheology.get_material(material)
    if m.units != "normalised":
        return df
    out = df.rename(columns={c: normalised_name(c) for c in df.columns})
    out.attrs.update(df.attrs)
    return out
