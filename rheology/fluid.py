"""Fluid-phase relations of Table 8: Beetstra drag, fluid viscosity and pore pressure."""

from __future__ import annotations

import numpy as np

from . import laws
from runkit.params import check_nonnegative, check_positive, check_range
from .materials import Material, get_material


def beetstra_F(phi, Re) -> np.ndarray:
    """Beetstra et al. (2007) normalised drag F(phi, Re) [-]; Re = rho_f |v_s - v_f| d / eta0."""
    return laws.beetstra_F(check_range("phi", phi, 0.0, 1.0, hi_closed=False),
                           check_nonnegative("Re", Re))


def drag_coefficient(phi, m: Material | str, Re=0.0) -> np.ndarray:
    """Darcy drag coefficient C = 18 phi (1 - phi) eta0 F(phi, Re)/d^2 [Pa s/m^2].

    The inter-phase force per volume is f_d = C (v_s - v_f) [N/m^3]. Needs d > 0.
    """
    m = get_material(m)
    check_positive("d", m.d, note=f"material {m.name}: drag needs a grain diameter")
    phi = check_range("phi", phi, 0.0, 1.0, hi_closed=False)
    return laws.drag_coefficient(phi, check_nonnegative("Re", Re), m.eta0, m.d)


def reynolds_number(relative_speed, m: Material | str) -> np.ndarray:
    """Particle Reynolds number rho_f |v_s - v_f| d / eta0 [-]; relative_speed [m/s] finite
    (any sign, or a vector component)."""
    m = get_material(m)
    m.require("rho_f")
    return m.rho_f * np.abs(check_range("relative_speed", relative_speed)) * m.d / m.eta0


def fluid_viscosity(phi, m: Material | str) -> np.ndarray:
    """Einstein-corrected fluid-phase viscosity eta0 (1 + 5/2 phi) [Pa s]."""
    m = get_material(m)
    return laws.fluid_viscosity(check_range("phi", phi, 0.0, 1.0, hi_closed=False), m.eta0)


def pore_pressure(rho_f, m: Material | str) -> np.ndarray:
    """Pore pressure p_f = kappa ln(rho_f/rho_0f) [Pa], rho_f the true fluid density [kg/m^3]."""
    m = get_material(m)
    m.require("kappa", "rho_f")
    return laws.pore_pressure(check_positive("rho_f", rho_f), m.rho_f, m.kappa)
