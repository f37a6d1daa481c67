"""The sample by mass: volume fractions from grain mass fractions (Eq. 20 of the Supplement), and
the command-line options every tier shares for it.

Cornstarch users weigh grains and liquid; the model needs the volume fraction of swollen grains.
Eq. (20) (Peters, Majumdar & Jaeger 2016) converts a mass fraction phi_W = m_cs/(m_cs + m_l) with
the grain, liquid and water densities, the swelling lambda (~0.3) and the pore space beta (~0.1).

- :class:`Densities`, :func:`volume_fraction`, :func:`mass_fraction` (the inverse),
  :func:`fractions_from_mass` (checked against the material's phi_j, naming ``--mass-fraction``);
- :func:`add_mass_fraction_options` and :func:`mass_fraction_phi`: ``--mass-fraction W [W ...]``,
  ``--grain-density``, ``--liquid-density``, ``--water-density``, ``--swelling``,
  ``--pore-fraction`` on every command (rheometer, shear1d, mpm2d), one validation path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from runkit.limits import DENSITY_MAX, DENSITY_MIN, ge, gt, le, lt
from runkit.params import Number, OutOfRange, Param, check_range

from .materials import Material
from .steady import phi_from_mass_fraction

#: Eq. (20) defaults (Supplement: lambda ~ 0.3, beta ~ 0.1) and densities where the material has
#: none [kg/m^3].
LAMBDA, BETA = 0.3, 0.1
RHO_GRAIN, RHO_LIQUID, RHO_WATER = 1620.0, 1000.0, 1000.0


@dataclass(frozen=True)
class Densities:
    """Eq. (20) inputs: grain, liquid and water densities [kg/m^3], lambda, beta [-]."""

    grain: float = RHO_GRAIN
    liquid: float = RHO_LIQUID
    water: float = RHO_WATER
    lam: float = LAMBDA
    beta: float = BETA

    @classmethod
    def for_material(cls, m: Material, grain=None, liquid=None, water=None, lam=None,
                     beta=None) -> "Densities":
        """The material's rho_s, rho_f where set, else the defaults; explicit values win."""
        return cls(grain if grain is not None else (m.rho_s or RHO_GRAIN),
                   liquid if liquid is not None else (m.rho_f or RHO_LIQUID),
                   water if water is not None else RHO_WATER,
                   lam if lam is not None else LAMBDA, beta if beta is not None else BETA)

    def describe(self) -> str:
        return (f"Eq. 20 with rho_grain = {self.grain:g}, rho_liquid = {self.liquid:g}, "
                f"rho_water = {self.water:g} kg/m^3, lambda = {self.lam:g}, beta = {self.beta:g}")


def volume_fraction(mass_fraction, dens: Densities = Densities()) -> np.ndarray:
    """Eq. (20): volume fraction phi [-] of mass fraction phi_W = m_cs/(m_cs + m_l) in (0, 1)."""
    return phi_from_mass_fraction(mass_fraction, dens.grain, dens.liquid, dens.water,
                                           dens.lam, dens.beta)


def mass_fraction(phi, dens: Densities = Densities()) -> np.ndarray:
    """Inverse of Eq. (20): the mass fraction phi_W giving volume fraction ``phi`` (0 < phi <
    (1 + lambda)(1 - beta)/((1 - beta) + beta rho_cs/rho_w), the value as phi_W -> 1)."""
    phi = np.asarray(phi, dtype=float)
    top = (1 + dens.lam) * (1 - dens.beta)
    base = (1 - dens.beta) + dens.beta * dens.grain / dens.water
    check_range("phi", phi, 0.0, top / base, lo_closed=False, hi_closed=False,
                note=f"the largest volume fraction Eq. 20 gives ({dens.describe()})")
    Q = (top / phi - base) * dens.liquid / dens.grain
    return 1.0 / (1.0 + Q)


def fractions_from_mass(mass_fractions, m: Material, dens: Densities) -> np.ndarray:
    """Volume fractions of ``mass_fractions`` for material ``m``; ValueError naming
    --mass-fraction and its valid range when one gives phi outside (0, phi_j)."""
    w = np.atleast_1d(np.asarray(mass_fractions, dtype=float))
    check_range("--mass-fraction", w, 0.0, 1.0, lo_closed=False, hi_closed=False)
    phi = np.atleast_1d(volume_fraction(w, dens))
    if np.any(phi >= m.phi_j):
        w_max = float(mass_fraction(min(m.phi_j, 0.999999 * _phi_top(dens)), dens))
        k = int(np.argmax(phi >= m.phi_j))
        raise OutOfRange("--mass-fraction", f"{w[k]:g}", f"(0, {w_max:.4g})",
                         f"it gives phi = {phi[k]:.4g} >= phi_j = {m.phi_j} of {m.name}; "
                         f"{dens.describe()}")
    return phi


def _phi_top(dens: Densities) -> float:
    return (1 + dens.lam) * (1 - dens.beta) / ((1 - dens.beta) + dens.beta * dens.grain
                                               / dens.water)


#: the Eq. (20) inputs' physical ranges, with their reasons
MASS_FRACTION = Param(gt(0.0, "a sample holds grains"), lt(1.0, "a suspension holds liquid"))
DENSITY = Param(DENSITY_MIN, DENSITY_MAX, unit="kg/m^3")
SWELLING = Param(ge(0.0, "swelling grains take up liquid, they never give up volume"),
                 le(10.0, "ten times the grain's own mass of liquid, far more than any swelling "
                          "grain takes up (cornstarch: ~0.3)"))
PORE = Param(ge(0.0, "a fraction of the grain's volume"),
             lt(1.0, "a grain is more than its pores"))


def add_mass_fraction_options(p, nargs="+") -> None:
    """``--mass-fraction`` (instead of a volume fraction) and the Eq. (20) inputs, on parser
    ``p``; ``nargs``: ``"+"`` for commands that take several fractions, ``None`` for one."""
    s = p.add_argument_group("sample by mass (Eq. 20 of the Supplement)")
    for name, param, what, more in (
            ("--mass-fraction", MASS_FRACTION, "grain mass fraction(s) m_grain/(m_grain + "
             "m_liquid), converted to volume fractions by Eq. 20 (instead of a volume fraction)",
             dict(nargs=nargs, metavar="W")),
            ("--grain-density", DENSITY, f"grain density [kg/m^3] (material's rho_s, else "
                                         f"{RHO_GRAIN:g})", {}),
            ("--liquid-density", DENSITY, f"liquid density [kg/m^3] (material's rho_f, else "
                                          f"{RHO_LIQUID:g})", {}),
            ("--water-density", DENSITY, f"water density [kg/m^3] ({RHO_WATER:g})", {}),
            ("--swelling", SWELLING, f"swelling parameter lambda of Eq. 20 ({LAMBDA:g})", {}),
            ("--pore-fraction", PORE, f"pore-space parameter beta of Eq. 20 ({BETA:g})", {})):
        s.add_argument(name, type=Number(name, param.lo, param.hi, unit=param.unit),
                       default=None, help=what, **more)


def densities_of(args, m: Material) -> Densities:
    """The :class:`Densities` of the parsed options (material's rho_s, rho_f where not given)."""
    return Densities.for_material(m, args.grain_density, args.liquid_density, args.water_density,
                                  args.swelling, args.pore_fraction)


def mass_fraction_phi(args, m: Material) -> tuple[list[float] | None, str]:
    """Volume fractions from ``--mass-fraction`` (None if not given) and a one-line note of the
    conversion (printed and written by the commands).

    Raises
    ------
    ValueError
        A fraction giving phi >= phi_j (the valid mass-fraction range is stated).
    """
    w = getattr(args, "mass_fraction", None)
    if w is None:
        return None, ""
    ws = [float(x) for x in np.atleast_1d(w)]
    dens = densities_of(args, m)
    phis = [float(p) for p in fractions_from_mass(ws, m, dens)]
    note = (f"mass fraction {', '.join(f'{x:g}' for x in ws)} -> phi = "
            f"{', '.join(f'{p:.5g}' for p in phis)} ({dens.describe()})")
    return phis, note
