"""Every parameter set of Baumgarten & Kamrin, as named, frozen, validated objects.

Each set is returned fresh by :func:`get_material` (``get_material("hermes2016", eta0=0.01)``)
and validated on construction: a bad value raises ``ValueError`` naming the field and its range.
:func:`list_materials` gives the names with their sources.

Units are SI (Pa, Pa s, kg/m^3, m) except the two Table 1 sets, which are in the paper's normalised
units (eta0 = gdot_0 = 1, stresses in eta0 gdot_0).

Sources (paper = Baumgarten & Kamrin, "A general constitutive model for dense, fine particle
suspensions validated in many geometries"):

============== ============================================================================
name            source
============== ============================================================================
singh2018_a     paper Table 1(a): fit to Singh et al. 2018 simulations, eta0/eta_B = 0
singh2018_b     paper Table 1(b): same, eta0/eta_B = 0.254 (phi_j - phi)
dhaene1993      paper Tables 2-3, ref. (12) d'Haene, Mewis & Fuller 1993 (PMMA)
frith1996       paper Tables 2-3, ref. (17) Frith, d'Haene, Buscall & Mewis 1996 (PMMA)
guy2015_a       paper Tables 2-3, ref. (20)(a) Guy, Hermes & Poon 2015 (PMMA)
guy2015_b       paper Tables 2-3, ref. (20)(b) Guy, Hermes & Poon 2015 (PMMA)
fall2015        paper Tables 2-3, ref. (16) Fall et al. 2015 (cornstarch)
hermes2016      paper Tables 2-3, ref. (22) Hermes et al. 2016 (cornstarch)
annular_shear   paper Table 4 on hermes2016 (Fig. 3; Peters, Majumdar & Jaeger 2016)
rod_impact      paper Table 5 on hermes2016, eta0 = 7 mPa s (Fig. 4; Waitukaitis & Jaeger 2012)
rod_impact_1cp  paper Table 5 on hermes2016, eta0 = 1 mPa s (Fig. 5)
intruder        paper Table 6 on hermes2016 (Figs. 6-7; Han, Peters & Jaeger 2016)
wheel           paper Table 7 on hermes2016 (Figs. 8-9, 'running on oobleck')
============== ============================================================================
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from runkit import limits
from runkit.io import atomic_write_json, check_input_file
from runkit.limits import Bound
from runkit.params import Param, check_range, shown

#: Units of every numeric field (SI sets; Table 1 sets use eta0 = gdot_0 = 1 instead).
FIELD_UNITS: dict[str, str] = {
    "phi_c": "-", "phi_j": "-", "a0": "-", "a_inf": "-", "mu_c": "-", "mu_2": "-", "b": "-",
    "tau_star": "Pa", "eta0": "Pa s", "varphi1": "1/(Pa s)", "alpha1": "-", "varphi2": "1/(Pa s)",
    "alpha2": "-", "Delta": "-", "xi_eps": "1/s", "K0": "-", "G": "Pa", "K": "Pa",
    "rho_s": "kg/m^3", "rho_f": "kg/m^3", "d": "m", "K3": "-", "K4": "-", "kappa": "Pa", "phi0": "-",
}

#: Physical limits (:mod:`runkit.limits`, each with its reason) of the dimensional fields a
#: command line may set (``--set NAME=VALUE`` of every tier); the Material itself asks them only
#: to be positive, which admits values no suspension has (G = 1e-300 Pa, d = 1e-155 m).
FIELD_LIMITS: dict[str, tuple] = {
    "tau_star": (limits.TAU_STAR_MIN, limits.TAU_STAR_MAX),
    "eta0": (limits.VISCOSITY_MIN, limits.VISCOSITY_MAX),
    **{k: (limits.MODULUS_MIN, limits.MODULUS_MAX) for k in ("G", "K", "kappa")},
    **{k: (limits.DENSITY_MIN, limits.DENSITY_MAX) for k in ("rho_s", "rho_f")},
    "d": (limits.GRAIN_MIN, limits.GRAIN_MAX),
}


def check_field_limit(label: str, name: str, value: float) -> None:
    """ValueError naming ``label`` when a field of :data:`FIELD_LIMITS` lies outside its
    physical limits (d = 0, the default, means no grain size: the grain-scale terms are off)."""
    if name in FIELD_LIMITS:
        Param(*FIELD_LIMITS[name], unit=FIELD_UNITS[name],
              also=(0.0,) if name == "d" else ()).check(label, value, static=True)

#: The variants of the local update's yield rules (field ``rules``; its kernel code is the
#: index): ``table8``, the published Table 8, and ``mpm_3d``, the rules of the author's code
#: (:mod:`rheology.local_update`).
RULES: tuple[str, ...] = ("table8", "mpm_3d")

#: Order of the fields in :meth:`Material.kernel_array` (read by the numba kernels): the numeric
#: fields, then the code of ``rules`` (its index in :data:`RULES`).
KERNEL_FIELDS: tuple[str, ...] = (
    "phi_c", "phi_j", "a0", "a_inf", "mu_c", "mu_2", "b", "tau_star", "eta0", "varphi1", "alpha1",
    "varphi2", "alpha2", "Delta", "xi_eps", "K0", "G", "K", "rho_s", "d", "K3", "rules",
)


def _own(why: str = "", value=None, closed: bool = True) -> Bound:
    """A bound of a Material's own validation, its reason naming the material (``value``: a
    field the bound is, else 0)."""
    at = (lambda p: p[value]) if value else 0.0
    return Bound(at, closed, lambda p: f"material {p['name']}" + (
        "; " + why.format(**p) if why else ""))


_VARPHI_WHY = ("varphi_i >= 0: 1/eta_B = sum varphi_i (phi_j - phi)^alpha_i (Eq. 9) is a rate of "
               "structure breakdown, never a build-up")
_ALPHA_WHY = "alpha_i >= 0: 1/eta_B (Eq. 9) falls, not diverges, as phi approaches phi_j"
#: The fields at least 0, with the physical reason (Table 8; Eqs. 7, 9).
_AT_LEAST_ZERO = {
    "b": "b >= 0: mu_p rises from mu_1 toward mu_2 as I_m grows past b (Table 8)",
    "varphi1": _VARPHI_WHY, "alpha1": _ALPHA_WHY, "varphi2": _VARPHI_WHY, "alpha2": _ALPHA_WHY,
    "xi_eps": "xi_eps >= 0: a rate of structure breakdown by diffusion (Eq. 7)",
    "d": "d >= 0: a grain size (0: none, the viscous limit without grain inertia)",
    "K3": "K3 >= 0: the dilation angle beta = K3 (phi - phi_eq) (Table 8) takes phi toward the "
          "critical state; a negative K3 drives it away",
    "K0": "K0 >= 0: the structure f relaxes toward its steady value at the rate K0 gdot_p (Table "
          "8); a negative K0 drives it away",
}

#: The fields above 0, with the physical reason (Eqs. 1, 3, 4, 6; Table 8).
_ABOVE_ZERO = {
    "phi_j": "phi_j > 0: a jamming fraction is a volume fraction",
    "phi_c": "phi_c > 0: a jamming fraction is a volume fraction",
    "a0": "a0 > 0: the contact stress grows as (a phi/(phi_m - phi))^2 (Eq. 1); a = 0 removes "
          "it",
    "mu_c": "mu_c > 0: a contact friction; without it the grains carry no shear stress (Eq. 1)",
    "tau_star": "tau* > 0: the repulsive stress scale of the frictional transition (Eq. 6)",
    "eta0": "eta0 > 0: the viscosity of the suspending liquid",
    "G": "G > 0: a shear modulus of the grain skeleton (Table 8)",
    "K": "K > 0: a bulk modulus of the grain skeleton (Table 8)",
    "rho_s": "rho_s > 0: a density", "rho_f": "rho_f > 0: a density",
    "kappa": "kappa > 0: the bulk modulus of the liquid",
    "phi0": "phi0 > 0: an initial volume fraction",
}
_DELTA_WHY = ("Delta in [0, 1]: phi* = phi_j + (phi_c - phi_j) Delta (Eq. 8) lies between phi_j "
              "and phi_c")

#: The model's range of every numeric field, each bound with its reason, checked once when a
#: Material is made (a field of :data:`FIELD_LIMITS` also meets its physical limits where a
#: command line or file sets it).
FIELDS: dict[str, Param] = {
    "phi_j": Param(_own(_ABOVE_ZERO["phi_j"], closed=False), Bound(1.0, False, lambda p: (
        f"material {p['name']}; phi_j < 1: grains jam before they fill the whole volume"))),
    "phi_c": Param(_own(_ABOVE_ZERO["phi_c"], closed=False),
                   _own("phi_c must be below phi_j = {phi_j}", "phi_j", closed=False)),
    "a0": Param(_own(_ABOVE_ZERO["a0"], closed=False)),
    "a_inf": Param(_own("a_inf >= a0 makes the stress-controlled steady state unique", "a0")),
    **{k: Param(_own(_ABOVE_ZERO[k], closed=False))
       for k in ("mu_c", "tau_star", "eta0", "G", "K", "rho_s", "rho_f", "kappa")},
    "mu_2": Param(_own("mu_2 >= mu_c", "mu_c")),
    **{k: Param(_own(why)) for k, why in _AT_LEAST_ZERO.items()},
    "Delta": Param(_own(_DELTA_WHY), Bound(1.0, True, lambda p: f"material {p['name']}; "
                                                               f"{_DELTA_WHY}")),
    "K4": Param(*[_own("only K4 = 0, the value of every scene of the paper, is implemented")] * 2),
    "phi0": Param(_own(_ABOVE_ZERO["phi0"], closed=False),
                  _own("below phi_j = {phi_j}", "phi_j", closed=False)),
}


def _check_field(name: str, value, param: Param, values: dict) -> None:
    """One field in its range at the other fields (as arrays are checked: subnormals pass);
    ValueError with the reason of the bound it fails."""
    lo, lo_closed, lo_why, hi, hi_closed, hi_why = param.bounds(values)
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = float("nan")
    below = lo is not None and (x < lo or (x == lo and not lo_closed))
    check_range(name, value, lo, hi, lo_closed=lo_closed, hi_closed=hi_closed,
                note=(lo_why if below else hi_why) or lo_why or hi_why)


@dataclass(frozen=True)
class Material:
    """A complete parameter set of the model (Table 8 with Eqs. 3, 4, 8, 9).

    Attributes
    ----------
    name, citation : str
        Registry name and the source of every number.
    units : str
        ``"SI"`` or ``"normalised"`` (eta0 = gdot_0 = 1; Table 1).
    phi_c, phi_j : float
        Frictional and frictionless jamming fractions, ``0 < phi_c < phi_j < 1`` (Eq. 3).
    a0, a_inf : float
        Dilatancy parameter at f = 0 and f = 1, ``0 < a0 <= a_inf`` (Eq. 4).
    mu_c : float
        Contact friction ``mu_1`` of Table 8 (``mu_c`` of Eq. 1), > 0.
    mu_2, b : float or None, float
        Table 8's ``mu_2`` and ``b``; ``mu_2 = None`` means ``mu_2 = mu_c`` (no b term), as in
        Baumgarten's code for this model.
    tau_star : float
        Repulsive stress scale tau* [Pa] (Eq. 6).
    eta0 : float
        Suspending-fluid viscosity [Pa s].
    varphi1, alpha1, varphi2, alpha2 : float
        Eq. 9 buckling resistance ``1/eta_B = sum_i varphi_i (phi_j - phi)^alpha_i``; varphi_i in
        1/(Pa s). All zero means eta_B = infinity.
    Delta : float
        Skeleton-compliance parameter of Eq. 8, in [0, 1]; 0 for the rheo-chaotic experiments,
        1 gives f_m = 1 (Table 1).
    xi_eps : float
        Brownian/electrostatic structure decay rate [1/s] (Eq. 7); 0 in every set of the paper.
    K0 : float or None
        Structure-rate scale (Eq. 5), >= 0; None where the paper gives none (steady fits).
    G, K : float or None
        Granular shear and bulk moduli [Pa], > 0; None where the paper gives none.
    rho_s, rho_f : float or None
        Grain and fluid true densities [kg/m^3].
    d : float
        Grain diameter [m]; 0 means the viscous limit (no grain inertia, no drag).
    K3, K4 : float
        Dilatancy and compaction-rate constants of Table 8 (4.715 and 0, from ref. 4).
    kappa : float or None
        Fluid bulk modulus [Pa] (pore pressure kappa ln(rho_f/rho_0f)); not given by the paper.
    phi0 : float or None
        Initial volume fraction of a scene.
    rules : str
        Yield rules of the local update, one of :data:`RULES`: ``"table8"`` (default, the
        published law) or ``"mpm_3d"`` (the author's code: elastic admissibility below jamming
        too; see :mod:`rheology.local_update`). Steady states do not depend on it.
    notes : str
        Choices we made where the paper is silent.
    """

    name: str
    citation: str
    phi_c: float
    phi_j: float
    a0: float
    a_inf: float
    mu_c: float
    tau_star: float
    eta0: float
    varphi1: float = 0.0
    alpha1: float = 0.0
    varphi2: float = 0.0
    alpha2: float = 0.0
    Delta: float = 0.0
    xi_eps: float = 0.0
    mu_2: float | None = None
    b: float = 0.0
    K0: float | None = None
    G: float | None = None
    K: float | None = None
    rho_s: float | None = None
    rho_f: float | None = None
    d: float = 0.0
    K3: float = 4.715
    K4: float = 0.0
    kappa: float | None = None
    phi0: float | None = None
    rules: str = "table8"
    units: str = "SI"
    notes: str = field(default="", compare=False)

    def __post_init__(self) -> None:
        n = f"material {self.name}"
        if self.units not in ("SI", "normalised"):
            raise ValueError(f"units = {self.units!r} must be 'SI' or 'normalised' ({n})")
        if self.rules not in RULES:
            raise ValueError(f"rules = {self.rules!r} must be one of "
                             f"{', '.join(map(repr, RULES))} ({n})")
        values = vars(self)
        for k, param in FIELDS.items():           # as arrays are checked: subnormals pass
            if values[k] is not None or k not in OPTIONAL_FIELDS:     # None: unset, allowed
                _check_field(k, values[k], param, values)
        if self.d > 0 and self.rho_s is None:
            raise ValueError(f"rho_s must be set (> 0 kg/m^3) when d = {self.d:g} m > 0 ({n})")

    # ------------------------------------------------------------------ derived parameters
    @property
    def mu2(self) -> float:
        """Table 8's mu_2 (equal to mu_c unless set)."""
        return self.mu_c if self.mu_2 is None else self.mu_2

    @property
    def phi_star(self) -> float:
        """phi* = phi_j + (phi_c - phi_j) Delta (Eq. 8): DST possible for phi_c <= phi <= phi*."""
        return self.phi_j + (self.phi_c - self.phi_j) * self.Delta

    def replace(self, **overrides) -> "Material":
        """Return a validated copy with fields overridden (unknown names raise ValueError).

        The set's own initial fraction phi0 follows a phi_j overridden at or below it (the
        default-fraction rule, :func:`default_fraction`, as :func:`scene_material` does for a
        user's material); a phi0 given with the overrides is checked as given."""
        names = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(overrides) - names)
        if unknown:
            raise ValueError(f"unknown material parameter(s) {unknown}; valid: {sorted(names)}")
        phi_j = overrides.get("phi_j")
        if "phi0" not in overrides and self.phi0 is not None and isinstance(phi_j, (int, float)) \
                and not self.phi0 < phi_j:
            m = dataclasses.replace(self, **overrides, phi0=None)
            return dataclasses.replace(m, phi0=default_fraction(m))
        return dataclasses.replace(self, **overrides)

    def require(self, *names: str) -> None:
        """Raise ValueError if any of ``names`` is unset (None) for this material."""
        for k in names:
            if getattr(self, k) is None:
                raise ValueError(f"{k} [{FIELD_UNITS.get(k, '-')}] is not set for material "
                                 f"{self.name} (the paper gives none): set it, e.g. {k}=...")

    def kernel_array(self) -> np.ndarray:
        """Fields in :data:`KERNEL_FIELDS` order for the numba kernels (None -> NaN; ``rules``
        as its index in :data:`RULES`)."""
        vals = [self.mu2 if k == "mu_2" else RULES.index(self.rules) if k == "rules"
                else getattr(self, k) for k in KERNEL_FIELDS]
        arr = np.array([np.nan if v is None else float(v) for v in vals])
        if self.rho_s is None:
            arr[KERNEL_FIELDS.index("rho_s")] = 0.0
        return arr

    def summary(self) -> str:
        """One line per numeric field with its unit."""
        lines = [f"{self.name}: {self.citation}"]
        for f in dataclasses.fields(self):
            if f.name in FIELD_UNITS:
                v = getattr(self, f.name)
                if v is not None:
                    lines.append(f"  {f.name:9s} = {v:<12.6g} [{FIELD_UNITS[f.name]}]")
        if self.notes:
            lines.append(f"  notes: {self.notes}")
        return "\n".join(lines)


# ---------------------------------------------------------------------------- the paper's sets
_PAPER = "Baumgarten & Kamrin, A general constitutive model for dense, fine particle suspensions"
_STEADY_NOTE = ("d not given for the steady fits: d = 0 is the viscous limit of Eq. (1)-(2); "
                "G, K, K0 not given (set them for transient tests)")


def _singh(fit: str) -> Material:
    common = dict(phi_c=0.585, phi_j=0.65, a0=0.455, a_inf=0.841, mu_c=1.0, eta0=1.0, Delta=1.0,
                  units="normalised", notes="normalised units eta0 = gdot_0 = 1; " + _STEADY_NOTE)
    ref = ("Singh, Mari, Denn & Morris, J. Rheol. 62, 457 (2018) simulations; "
           f"fit of {_PAPER}, Table 1({fit})")
    if fit == "a":
        return Material(name="singh2018_a", citation=ref, tau_star=1.74, **common)
    return Material(name="singh2018_b", citation=ref, tau_star=1.44, varphi1=0.254, alpha1=1.0,
                    **common)


#: Tables 2-3: name -> (reference, phi_c, phi_j, a0, a_inf, tau* [Pa], eta0 [mPa s], mu_c,
#: varphi1 [1/(Pa s)], alpha1, varphi2 [1/(Pa s)], alpha2).
_TABLE2 = {
    "dhaene1993": ("d'Haene, Mewis & Fuller, J. Colloid Interface Sci. 156, 350 (1993), PMMA",
                   0.57, 0.65, 1.08, 1.08, 5.21, 56, 0.3, 8.83e6, 6, 0, 0),
    "frith1996": ("Frith, d'Haene, Buscall & Mewis, J. Rheol. 40, 531 (1996), PMMA",
                  0.548, 0.642, 1.08, 1.08, 17.93, 130, 0.3, 1.79e11, 12, 4.5, 0.1),
    "guy2015_a": ("Guy, Hermes & Poon, PRL 115, 088304 (2015), PMMA, fit (a)",
                  0.56, 0.617, 1.577, 1.577, 423.0, 2.4, 0.3, 3e6, 5, 9e-2, 0.1),
    "guy2015_b": ("Guy, Hermes & Poon, PRL 115, 088304 (2015), PMMA, fit (b)",
                  0.563, 0.610, 1.09, 1.538, 3.5, 2.4, 0.3, 1.0e6, 6, 0, 0),
    "fall2015": ("Fall et al., PRL 114, 098301 (2015), cornstarch",
                 0.38, 0.454, 1.00, 1.00, 0.116, 0.89, 1.19, 4.0e4, 3, 0, 0),
    "hermes2016": ("Hermes et al., J. Rheol. 60, 905 (2016), cornstarch",
                   0.436, 0.535, 0.8, 0.8, 5.35, 6, 1.19, 1.86e4, 4, 9.3e-3, 0.1),
}


def _table2(name: str) -> Material:
    ref, phi_c, phi_j, a0, a_inf, tau_star, eta0_mPas, mu_c, v1, a1, v2, a2 = _TABLE2[name]
    return Material(name=name, citation=f"{ref}; fit of {_PAPER}, Tables 2-3", phi_c=phi_c,
                    phi_j=phi_j, a0=a0, a_inf=a_inf, mu_c=mu_c, tau_star=tau_star,
                    eta0=eta0_mPas * 1e-3, varphi1=v1, alpha1=a1, varphi2=v2, alpha2=a2,
                    Delta=0.0, notes=_STEADY_NOTE)


_SCENE_NOTE = ("d = 5.85 um, K3 = 4.715, K4 = 0 from the text; kappa (fluid bulk modulus) is not "
               "given by the paper: our choice kappa = K keeps the fluid and skeleton wave speeds "
               "alike and elastic strains small")
_NO_PHI0 = "; phi0 not given by the paper (set it per run)"


def _scene(name, table, ref, eta0, rho_s, rho_f, G, K, K0, phi0=None, extra_note=""):
    """A scene's set of Tables 4-7: the Hermes 2016 steady fit with its moduli and densities."""
    return _table2("hermes2016").replace(
        name=name, citation=f"{ref}; {_PAPER}, Table {table} with the Hermes 2016 steady fit",
        eta0=eta0, rho_s=rho_s, rho_f=rho_f, G=G, K=K, K0=K0, d=5.85e-6, K3=4.715, K4=0.0,
        kappa=K, phi0=phi0, notes=_SCENE_NOTE + extra_note)


_REGISTRY: dict[str, Callable[[], Material]] = {
    "singh2018_a": lambda: _singh("a"),
    "singh2018_b": lambda: _singh("b"),
    **{k: (lambda k=k: _table2(k)) for k in _TABLE2},
    "annular_shear": lambda: _scene(
        "annular_shear", 4, "Peters, Majumdar & Jaeger, Nature 532, 214 (2016)", 10e-3, 1620.0,
        1620.0, 3.8e5, 8.3e5, 0.06, phi0=0.505,
        extra_note="; density matched: rho_s = rho_f = rho = 1620 kg/m^3"),
    **{name: (lambda name=name, eta0=eta0, fig=fig: _scene(
        name, 5, f"Waitukaitis & Jaeger, Nature 487, 205 (2012), Fig. {fig}", eta0, 1620.0,
        1000.0, 3.8e7, 8.3e7, 1.0, extra_note=_NO_PHI0))
       for name, eta0, fig in (("rod_impact", 7e-3, 4), ("rod_impact_1cp", 1e-3, 5))},
    "intruder": lambda: _scene(
        "intruder", 6, "Han, Peters & Jaeger, Nat. Commun. 7, 12243 (2016)", 4.6e-3, 1620.0,
        1620.0, 3.8e7, 8.3e7, 0.2, phi0=0.47,
        extra_note="; phi0 = 0.47 as in Fig. 6(a)-(e); Fig. 7 varies 0.46-0.50"),
    "wheel": lambda: _scene("wheel", 7, "running on oobleck, Figs. 8-9", 1e-3, 1620.0, 1620.0,
                            3.8e5, 8.3e5, 1.0, extra_note=_NO_PHI0),
}

#: The six experimental steady fits of Fig. 2, in the paper's panel order (a)-(f).
FIG2_MATERIALS: tuple[str, ...] = ("dhaene1993", "frith1996", "guy2015_a", "guy2015_b",
                                   "fall2015", "hermes2016")


# ---------------------------------------------------------------------------- material files
#: ``format`` tag of a material file written by :func:`save_material`.
MATERIAL_FILE_FORMAT = "suspension-toolkit material"


def material_to_dict(m: Material) -> dict:
    """Every field of ``m`` as plain JSON values (None for unset optional fields)."""
    return {f.name: getattr(m, f.name) for f in dataclasses.fields(m)}


def material_from_dict(data: dict, source: str = "material file") -> Material:
    """A validated Material from a dict of fields (as written by :func:`material_to_dict`).

    Raises
    ------
    ValueError
        Not a dict, unknown or missing fields, a non-numeric value or a value outside its range
        (the Material's own validation), each naming ``source``.
    """
    if not isinstance(data, dict):
        raise ValueError(f"{source}: the material must be a JSON object of fields")
    known = {f.name: f for f in dataclasses.fields(Material)}
    unknown = sorted(set(data) - set(known))
    if unknown:
        raise ValueError(f"{source}: unknown material field(s) {unknown}; valid: {sorted(known)}")
    required = [n for n, f in known.items() if f.default is dataclasses.MISSING
                and f.default_factory is dataclasses.MISSING]
    missing = [n for n in required if n not in data]
    if missing:
        raise ValueError(f"{source}: missing material field(s) {missing}")
    values = {}
    for k, v in data.items():
        if k in ("name", "citation", "units", "notes", "rules"):
            if not isinstance(v, str):
                raise ValueError(f"{source}: {k} = {v!r} must be a string")
        elif v is None:
            if known[k].default is not None:
                raise ValueError(f"{source}: {k} = null is not allowed (a number is required)")
        elif isinstance(v, bool) or not isinstance(v, (int, float)):
            raise ValueError(f"{source}: {k} = {v!r} is not a number")
        values[k] = float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else v
    try:
        return Material(**values)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None


def save_material(path, m: Material, **extra) -> Path:
    """Write ``m`` as a material file (strict JSON, atomically): ``{"format", "material":
    {fields}, **extra}`` (e.g. ``provenance=...``, ``fit=...``). :func:`get_material` reads it."""
    doc = {"format": MATERIAL_FILE_FORMAT, "version": 1, "material": material_to_dict(m), **extra}
    return atomic_write_json(path, doc)


def load_material(path) -> Material:
    """Read a material file (:func:`save_material`'s layout, or a bare object of fields) and
    validate it like a built-in set.

    Raises
    ------
    ValueError
        The file is missing, not JSON, or its material is invalid (named with the file).
    """
    def no_nan(token):
        raise ValueError(f"{token} is not a number in strict JSON")

    path = check_input_file("material file", path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"), parse_constant=no_nan)
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"material file {str(path)!r} is not valid JSON "
                         f"({' '.join(str(exc).split())[:100]})") from None
    data = doc.get("material", doc) if isinstance(doc, dict) else doc
    if isinstance(data, dict):
        data = {k: v for k, v in data.items() if k not in ("format", "version")}
        for k, v in data.items():           # the physical limits a --set meets, likewise
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                check_field_limit(f"material file {path.name}: {k}", k, float(v))
    return material_from_dict(data, f"material file {path.name}")


def _is_material_file(name) -> bool:
    text = str(name)
    return text.lower().endswith(".json") or (("/" in text or "\\" in text) and Path(text).exists())


def material_names() -> list[str]:
    """Names of every registered parameter set."""
    return list(_REGISTRY)


def get_material(name: str | Material, **overrides) -> Material:
    """Return a fresh, validated parameter set, optionally with fields overridden.

    Parameters
    ----------
    name : str, path or Material
        A registry name (see :func:`material_names`), a material file (``*.json``, written by
        :func:`save_material`, e.g. ``fit/material.json`` from ``rheometer fit``) or a
        Material to copy.
    **overrides
        Field values to replace, e.g. ``eta0=0.01`` [Pa s]; the result is validated.

    Raises
    ------
    ValueError
        Unknown name or field, an unreadable or invalid material file, or an override outside
        its valid range.
    """
    if isinstance(name, Material):
        base = name
    elif _is_material_file(name):
        base = load_material(name)
    else:
        key = str(name).strip().lower()
        if key not in _REGISTRY:
            raise ValueError(f"unknown material {name!r}; valid: {', '.join(_REGISTRY)}")
        base = _REGISTRY[key]()
    return base.replace(**overrides) if overrides else base


#: Text (metadata) fields of a Material: never set from the command line (``--set``); the
#: text field ``rules`` is a model choice and is settable.
TEXT_FIELDS: tuple[str, ...] = ("name", "citation", "units", "notes")
#: Numeric fields that may be unset (None); ``--set NAME=none`` unsets them.
OPTIONAL_FIELDS: tuple[str, ...] = ("mu_2", "K0", "G", "K", "rho_s", "rho_f", "kappa", "phi0")


def settable_fields() -> list[str]:
    """The parameters ``--set NAME=VALUE`` may change: every numeric field (:data:`FIELD_UNITS`)
    and ``rules``, sorted; the text fields (:data:`TEXT_FIELDS`) are not settable."""
    return sorted([*FIELD_UNITS, "rules"])


def split_set_item(text: str, option: str = "--set"):
    """``NAME=VALUE`` of one ``--set`` word as ``(name, value)`` (stripped text); ``none``/``null``
    as the value gives None (an optional parameter unset).

    Raises
    ------
    ValueError
        One line when the word has no ``=`` or an empty name or value.
    """
    if "=" not in text:
        raise ValueError(f"{option} expects NAME=VALUE, got {text!r}")
    name, value = (s.strip() for s in text.split("=", 1))
    if not name or not value:
        raise ValueError(f"{option} {text!r}: empty name or value (NAME=VALUE; an optional "
                         f"parameter is unset with NAME=none)")
    return name, None if value.lower() in ("none", "null") else value


def check_set_override(name: str, value, option: str = "--set"):
    """Validate one ``--set NAME=VALUE`` of a command line; return ``(name, value)``.

    ``value`` is a number, None (``none``: only for :data:`OPTIONAL_FIELDS`) or text as typed;
    ``rules`` takes one of :data:`RULES` (returned as text). A field of :data:`FIELD_LIMITS` is
    checked against its physical limits here; the rest of a number's range by the Material
    when it is built.

    Raises
    ------
    ValueError
        One line naming the key and the settable keys when ``name`` is a text field or unknown;
        naming the key and its value when the value is not a finite number (or a ``none`` where
        a number is required).
    """
    valid = ", ".join(settable_fields())
    if name in TEXT_FIELDS:
        raise ValueError(f"{option} {name}: {name} is a text field of the material, not a settable "
                         f"parameter; settable: {valid}")
    if name not in FIELD_UNITS and name != "rules":
        raise ValueError(f"{option} {name}: unknown material parameter; settable: {valid}")
    if name == "rules":
        if not isinstance(value, str) or value.strip().lower() not in RULES:
            shown = "none" if value is None else repr(value)
            raise ValueError(f"{option} rules = {shown} is not one of {', '.join(RULES)}")
        return name, value.strip().lower()
    if value is None:
        if name not in OPTIONAL_FIELDS:
            raise ValueError(f"{option} {name} = none: {name} needs a number (only "
                             f"{', '.join(OPTIONAL_FIELDS)} can be unset)")
        return name, None
    text = value if isinstance(value, str) else shown(value)
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            raise ValueError(f"{option} {name} = {value!r} is not a number "
                             f"[{FIELD_UNITS[name]}]") from None
    if isinstance(value, bool) or not np.isfinite(value):
        raise ValueError(f"{option} {name} = {text}: must be finite{_finite_note(name)}")
    check_field_limit(f"{option} {name}", name, float(value))
    return name, float(value)


def _finite_note(name: str) -> str:
    """The range and reasons a refusal of a non-finite ``--set NAME`` states."""
    if name in FIELD_LIMITS:
        lo, hi = FIELD_LIMITS[name]
        why = "; ".join(dict.fromkeys(w for w in (lo.why, hi.why) if w))
        return (f"; valid range {Param(lo, hi, unit=FIELD_UNITS[name]).range_text(static=True)}"
                + (f" ({why})" if why else ""))
    why = _ABOVE_ZERO.get(name) or _AT_LEAST_ZERO.get(name) or (
        _DELTA_WHY if name == "Delta" else "")
    return f" ({why})" if why else ""


def set_argument(text: str):
    """``type=`` of a command line's ``--set NAME=VALUE`` (argparse): :func:`split_set_item` then
    :func:`check_set_override`; a refusal is one ``argparse.ArgumentTypeError`` line."""
    try:
        return check_set_override(*split_set_item(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def set_overrides(items, option: str = "--set") -> dict:
    """The ``(name, value)`` pairs of repeated ``--set`` words as a dict; ValueError naming a
    parameter given twice."""
    names = [k for k, _ in items or []]
    twice = sorted({k for k in names if names.count(k) > 1})
    if twice:
        raise ValueError(f"{option} {twice[0]} given twice; give each parameter once")
    return dict(items or [])


#: Fields a steady flow curve cannot determine: a scene's own (moduli, densities, grain size,
#: structure-rate scale, fluid bulk modulus, initial fraction; Tables 4-7 and the text).
SCENE_FIELDS = ("G", "K", "K0", "rho_s", "rho_f", "d", "K3", "K4", "kappa", "phi0")


def scene_material(scene_set: str | Material, material: str | Material | None = None,
                   **overrides) -> Material:
    """A scene's parameter set with a user's steady fit in place of the paper's.

    The paper runs every scene on the Hermes 2016 steady fit with the scene's Table 4-7 moduli,
    densities and K0. ``scene_material("annular_shear", "fit/material.json")`` does the same
    with the user's material: its steady-flow parameters (phi_c, phi_j, a0, a_inf, mu_c, tau*,
    eta0, eta_B, Delta, ...) are used, and each of :data:`SCENE_FIELDS` the material leaves unset
    (None; d = 0, the viscous limit of a steady fit) is taken from the scene's set, except a
    scene phi0 at or above the material's phi_j: then phi0 follows the default-fraction rule of
    :func:`default_fraction` (the rule every command uses).

    Parameters
    ----------
    scene_set : str or Material
        The scene's own set (e.g. ``"annular_shear"``, ``"rod_impact"``).
    material : str, path, Material or None
        The user's material (name, ``*.json`` file or Material); None: the scene's set.
    **overrides
        Field values applied last (validated).

    Raises
    ------
    ValueError
        Unknown or invalid material, a normalised (Table 1) set in an SI scene, bad overrides.
    """
    scene = get_material(scene_set)
    if material is None:
        return scene.replace(**overrides) if overrides else scene
    user = get_material(material)
    if user.units != scene.units:
        raise ValueError(f"material {user.name!r} is in {user.units} units; the scene needs "
                         f"{scene.units} units (e.g. a fitted material.json or hermes2016)")
    unset = {k for k in SCENE_FIELDS if getattr(user, k) is None}
    if user.d == 0.0:                        # 0: the viscous limit of a steady fit, no grain size
        unset.add("d")
    fill = {k: getattr(scene, k) for k in unset}
    if "phi0" in fill and (fill["phi0"] is None or fill["phi0"] >= user.phi_j):
        fill["phi0"] = default_fraction(user)
    return user.replace(**fill, **overrides) if (fill or overrides) else user


#: Default volume fractions, one rule (:data:`RULE`) for every command of every tier: phi_c + s
#: (phi_j - phi_c), inside the DST window phi_c <= phi < phi_j for a set with DST (finite eta_B,
#: Eq. 9; Hermes 2016: 0.48, 0.50, 0.52), below phi_c, where it flows at every stress, for a set
#: without (Singh (a) shear-jams above phi_c); rounded to 0.005 (finer where that would merge
#: two) and kept inside (0, phi_j).
DST_POSITIONS = (0.45, 0.65, 0.85)
NO_DST_POSITIONS = (-1.5, -0.75, -0.25)
#: the roundings tried in turn: the first that keeps the three fractions distinct (a narrow
#: phi_c-phi_j window, e.g. a phi_j set close to phi_c, merges them at 0.005)
ROUNDING = (0.005, 0.001, 0.0001)
RULE = ("default phi: sets with DST (finite eta_B) phi_c + (0.45, 0.65, 0.85)(phi_j - phi_c), "
        "sets without DST (Singh (a)) phi_c + (-1.5, -0.75, -0.25)(phi_j - phi_c), rounded to "
        "0.005 (finer where that would merge two); one-phi commands take the middle one")


def has_dst(material) -> bool:
    """Whether the set shows DST: a finite buckling resistance eta_B (Eq. 9)."""
    m = material if isinstance(material, Material) else get_material(material)
    return (m.varphi1 + m.varphi2) > 0


def default_fractions(material) -> list[float]:
    """The three default volume fractions of ``material`` (name or Material), ascending."""
    m = material if isinstance(material, Material) else get_material(material)
    exact = [m.phi_c + x * (m.phi_j - m.phi_c)
             for x in (DST_POSITIONS if has_dst(m) else NO_DST_POSITIONS)]
    for step in ROUNDING:
        out = [float(round(min(max(round(phi / step) * step, step), m.phi_j - step), 6))
               for phi in exact]
        if len(set(out)) == len(out):
            return out
    return exact


def default_fraction(material) -> float:
    """The single default volume fraction (the middle of :func:`default_fractions`)."""
    return default_fractions(material)[1]


def list_materials() -> list[tuple[str, str]]:
    """``(name, citation)`` for every registered parameter set."""
    return [(n, f().citation) for n, f in _REGISTRY.items()]
