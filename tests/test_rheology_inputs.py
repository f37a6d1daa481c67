"""Every public rheology function refuses bad input with one line naming the parameter and range."""

import numpy as np
import pytest

import rheology as r

H = r.get_material("hermes2016")
S = r.get_material("annular_shear")
NAN = float("nan")

CASES = [
    (lambda: r.steady_state_stress(1.0, 0.535, H), "phi", "(0, 0.535)"),        # at jamming
    (lambda: r.steady_state_stress(1.0, 0.6, H), "phi", "(0, 0.535)"),          # above
    (lambda: r.steady_state_stress(-1.0, 0.5, H), "taubar", "[0, inf)"),
    (lambda: r.steady_state_stress(NAN, 0.5, H), "taubar", "finite"),
    (lambda: r.steady_states_rate(0.0, 0.5, H), "shear_rate", "(0, inf)"),
    (lambda: r.steady_states_rate(1.0, np.array([0.5, 0.55]), H), "phi", "(0, 0.535)"),
    (lambda: r.steady_states_mixture_stress(-2.0, 0.5, H), "shear_stress", "(0, inf)"),
    (lambda: r.gdot_dst(0.40, H), "phi", "[0.436, 0.535)"),
    (lambda: r.relative_viscosity(0.5, 1.2, H), "f", "[0, 1]"),
    (lambda: r.normal_viscosity(0.9, 0.0, H), "phi", "(0, 0.535)"),
    (lambda: r.critical_shear_rate(1.0, 1.0, 0.1, H), "phi", "(0, 1)"),
    (lambda: r.phi_m(-0.1, H), "f", "[0, 1]"),
    (lambda: r.f_max(1.0, H), "phi", "[0, 1)"),
    (lambda: r.eta_B(NAN, H), "phi", "finite"),
    (lambda: r.softening(1.0, 0.0, 0.5, H), "gdot_p", "(0, inf)"),
    (lambda: r.structure_step(0.1, 1.0, 1.0, 0.5, -1e-3, S), "dt", "(0, inf)"),
    (lambda: r.structure_rate(0.1, 1.0, 1.0, 0.5, H), "K0", "not set"),
    (lambda: r.phi_from_mass_fraction(1.0, 1630, 1000), "phi_w", "(0, 1)"),
    (lambda: r.phi_from_mass_fraction(0.5, -1630, 1000), "rho_cs", "(0, inf)"),
    (lambda: r.drag_coefficient(0.5, H), "d", "(0, inf)"),
    (lambda: r.drag_coefficient(1.0, S), "phi", "[0, 1)"),
    (lambda: r.beetstra_F(0.3, -1.0), "Re", "[0, inf)"),
    (lambda: r.pore_pressure(0.0, S), "rho_f", "(0, inf)"),
    (lambda: r.pore_pressure(1000.0, H), "kappa", "not set"),
    (lambda: r.inertial_numbers(1.0, 0.0, S), "p", "(0, inf)"),
]


@pytest.mark.parametrize("call, name, rng", CASES)
def test_bad_input_is_named_with_its_range(call, name, rng):
    with pytest.raises(ValueError) as err:
        call()
    msg = str(err.value)
    assert msg.startswith(name + " ") or msg.startswith(name + " =") or f"{name} [" in msg, msg
    assert rng in msg and "\n" not in msg, msg
