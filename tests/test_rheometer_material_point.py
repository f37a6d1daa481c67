"""Material-point mode: the shared Table 8 update in homogeneous simple shear."""

import numpy as np
import pytest

import rheology
from rheometer import simple_shear_point, tensor_reference
from rheology.local_update import NOUT
from rheometer.material_point import YIELD_TOL, yield_residual
from validation.cases_rheometer import convergence_study

HERMES = rheology.get_material("hermes2016")


@pytest.mark.parametrize("phi, rate", [(0.45, 1.0), (0.52, 0.05)])
def test_volume_controlled_steady_state_is_eq_1_2(phi, rate):
    ss = rheology.steady_states_rate(rate, phi, HERMES)
    tau_ss = float(ss.taubar[np.flatnonzero(ss.stable)[0]])
    df = simple_shear_point(HERMES, phi, rate, 40.0 / rate, 0.01 / rate, G=1e6, K0=1.0,
                            stress0=0.5 * tau_ss, points=50)
    end = df.iloc[-1]
    f = end["f"]
    eta_s = end["shear_stress_Pa"] / (HERMES.eta0 * rate)
    eta_n = end["granular_pressure_Pa"] / (HERMES.eta0 * rate)
    assert eta_s == pytest.approx(float(rheology.granular_viscosity(phi, f, HERMES)), rel=1e-8)
    assert eta_n == pytest.approx(float(rheology.normal_viscosity(phi, f, HERMES)), rel=1e-8)
    assert end["shear_stress_Pa"] == pytest.approx(tau_ss, rel=1e-7)
    assert (df["phi"] == phi).all()


def test_pressure_control_holds_the_pressure_and_compacts():
    phi_ss, rate = 0.50, 0.5
    ss = rheology.steady_states_rate(rate, phi_ss, HERMES)
    k = int(np.flatnonzero(ss.stable)[0])
    p = float(ss.pressure[k])
    df = simple_shear_point(HERMES, phi_ss - 0.005, rate, 80.0, 1e-3, control="pressure",
                            pressure=p, G=1e4, K0=1.0, stress0=0.5 * float(ss.taubar[k]),
                            points=80)
    assert np.allclose(df["granular_pressure_Pa"].iloc[1:], p, rtol=1e-9)
    assert df["phi"].iloc[-1] == pytest.approx(phi_ss, rel=1e-6)
    assert df["f"].iloc[-1] == pytest.approx(float(ss.f[k]), rel=1e-6)


def test_first_order_convergence_to_the_ida_tensor_solution():
    """Backward-Euler plastic step, explicit Jaumann spin, staggered f: order 1 in dt."""
    res = convergence_study(scenarios=(("volume", 2.0), ("volume", 0.5)), levels=range(8, 12))
    for (ctrl, fac), (dts, errs, ref, _) in res.items():
        orders = np.log2(errs[:-1] / errs[1:])
        assert np.all(orders > 0.9) and np.all(orders < 1.3), (ctrl, fac, orders)
        assert errs[-1] < 1e-3


def test_tensor_reference_regime_switch_and_pressure_drift():
    st = rheology.steady_state_stress(1.0, 0.50, HERMES)
    ref = tensor_reference(HERMES, 0.50, 0.5 * float(st.shear_rate), 2.0, control="pressure",
                           pressure=float(st.pressure), G=100.0, K0=1.0, stress0=1.0)
    assert [w for _, w in ref.attrs["switches"]] == ["dilatant shear flow"]
    assert ref.attrs["pressure_drift"] < 1e-8
    assert ref["phi"].iloc[-1] > 0.50                       # slowing down compacts


def test_large_step_under_pressure_control_is_substepped():
    """A step of dt = 1 s at 1 1/s (strain 1 per step, whose dilation alone would exceed the
    elastic strain p/K) is split into sub-steps within the spin bound and reaches the steady
    state of Eqs. (1)-(2) at the imposed pressure."""
    ss = rheology.steady_states_rate(1.0, 0.45, HERMES)
    p = float(ss.pressure[0])
    df = simple_shear_point(HERMES, 0.45, 1.0, 30.0, 1.0, control="pressure", pressure=p,
                            G=1e4, K0=1.0, stress0=0.5 * float(ss.taubar[0]))
    assert df.attrs["max_substeps_per_step"] >= 1.0 / df.attrs["strain_per_substep_max"]
    assert np.allclose(df["granular_pressure_Pa"].iloc[1:], p, rtol=1e-9)
    st = rheology.steady_state_stress(df["granular_shear_stress_Pa"].iloc[-1],
                                      df["phi"].iloc[-1], HERMES)
    # the steady plastic rate is gdot cos(theta), sin(theta) = taubar/G (Jaumann, see
    # tests/test_rheometer_reliability.py); here theta ~ 1e-4
    s = df["granular_shear_stress_Pa"].iloc[-1] / 1e4
    assert float(st.shear_rate) == pytest.approx(np.sqrt(1 - s * s), rel=1e-6)


def test_volume_control_is_stable_at_huge_steps():
    df = simple_shear_point(HERMES, 0.50, 0.5, 200.0, 10.0, G=1e4, K0=1.0, stress0=0.5)
    ss = rheology.steady_states_rate(0.5, 0.50, HERMES)
    assert df["shear_stress_Pa"].iloc[-1] == pytest.approx(float(ss.taubar[0]), rel=1e-2)
    assert np.all(np.isfinite(df["shear_stress_Pa"]))


def test_start_from_rest_keeps_contact():
    df = simple_shear_point(HERMES, 0.50, 0.5, 2.0, 1e-3, G=1e4, K0=1.0)
    assert df["case"].iloc[0] == "initial"
    assert (df["granular_pressure_Pa"].iloc[1:] > 0).all()
    assert (df["case"].iloc[1:] != "separated").all()


def test_yield_residual_flags_off_surface_states():
    out = np.zeros(NOUT)
    out[12], out[10], out[11], out[4], out[8] = 2, 1.0, 0.5, 1.9, 0.1    # f1 = 1 - 2.0*0.5 = 0
    assert yield_residual(out) < 1e-15
    out[10] = 1.1
    assert yield_residual(out) > YIELD_TOL
    out[12] = 0                                                         # elastic: not checked
    assert yield_residual(out) == 0.0


@pytest.mark.parametrize("kwargs, match", [
    (dict(dt=2.0, t_end=1.0), "dt"),
    (dict(control="shear"), "control"),
    (dict(control="pressure"), "pressure control needs"),
    (dict(phi=0.6), "phi = 0.6 is outside"),
    (dict(rate=-1.0), "rate"),
    (dict(G=0.0), "G"),
])
def test_bad_input(kwargs, match):
    args = dict(material=HERMES, phi=0.5, rate=1.0, t_end=1.0, dt=1e-2) | kwargs
    with pytest.raises(ValueError, match=match):
        simple_shear_point(args.pop("material"), args.pop("phi"), args.pop("rate"),
                           args.pop("t_end"), args.pop("dt"), **args)
