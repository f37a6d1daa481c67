"""The 0-D model on IDA: exact solutions, events, steady limits, Jacobian, physics checks."""

import numpy as np
import pytest

import rheology
from rheometer import Rheometer, Step, creep, model, relax, startup
from rheometer.transient import State

HERMES = rheology.get_material("hermes2016")


def _eta(phi, f, m=HERMES):
    """Granular viscosity eta0 eta_g(phi, f) [Pa s] (Eq. 1 granular part)."""
    return m.eta0 * float(rheology.granular_viscosity(phi, f, m))


@pytest.mark.parametrize("phi, tau0, G", [(0.52, 10.0, 1e4), (0.45, 1.0, 1e3), (0.50, 100.0, 1e5)])
def test_frozen_structure_relaxation_is_exponential(phi, tau0, G):
    """K0 = 0: taubar' = -G taubar/eta with eta fixed, so taubar = taubar0 exp(-G t/eta)."""
    df = relax(HERMES, phi, tau0, 50.0, G=G, K0=0.0, rtol=1e-10)
    f0 = float(rheology.steady_state_stress(tau0, phi, HERMES).f)
    exact = tau0 * np.exp(-G * df["time_s"] / _eta(phi, f0))
    assert np.max(np.abs(df["shear_stress_Pa"] - exact)) < 1e-8 * tau0
    assert np.allclose(df["f"], f0, rtol=0, atol=1e-14)
    assert np.all(df["shear_rate_per_s"] == 0.0)


def test_frozen_structure_startup_is_maxwell():
    """K0 = 0 from rest with f0: taubar = eta gdot (1 - exp(-G t/eta))."""
    phi, rate, G, f0 = 0.50, 0.3, 1e3, 0.05
    df = startup(HERMES, phi, rate, 20.0, G=G, K0=0.0, f0=f0, rtol=1e-10)
    eta = _eta(phi, f0)
    exact = eta * rate * (1 - np.exp(-G * df["time_s"] / eta))
    assert np.max(np.abs(df["granular_shear_stress_Pa"] - exact)) < 1e-8 * eta * rate
    assert np.allclose(df["strain"], rate * df["time_s"], rtol=1e-9, atol=1e-12)


def test_frozen_structure_creep_exact():
    """K0 = 0: taubar' = G ((tau - taubar)/eta_f - taubar/eta): exponential approach to
    tau eta/(eta + eta_f)."""
    phi, tau, G = 0.48, 2.0, 1e3
    df = creep(HERMES, phi, tau, 1.0, G=G, K0=0.0, rtol=1e-10)
    eta, eta_f = _eta(phi, 0.0), HERMES.eta0 * (1 + 2.5 * phi)
    rate = G * (1 / eta_f + 1 / eta)
    exact = tau * eta / (eta + eta_f) * (1 - np.exp(-rate * df["time_s"]))
    assert np.max(np.abs(df["granular_shear_stress_Pa"] - exact)) < 1e-8 * tau
    assert np.allclose(df["shear_stress_Pa"], tau, rtol=1e-12)        # mixture stress imposed


def test_newtonian_limit_at_low_stress():
    """tau << tau*: f -> 0 and the viscosity is the low-stress plateau of Eq. (24)."""
    phi = 0.45
    tau = 1e-5 * HERMES.tau_star
    df = creep(HERMES, phi, tau, 10.0, G=1e4, K0=1.0, rtol=1e-10)
    expected = HERMES.eta0 * float(rheology.viscosity_low_limit(phi, HERMES))
    assert df["viscosity_Pa_s"].iloc[-1] == pytest.approx(expected, rel=1e-6)


@pytest.mark.parametrize("phi, rate", [(0.45, 1.0), (0.52, 0.05)])
def test_startup_ends_on_stable_steady_state(phi, rate):
    df = startup(HERMES, phi, rate, 60.0 / rate, G=1e4, K0=1.0, rtol=1e-9)
    end = df.iloc[-1]
    ss = rheology.steady_states_rate(rate, phi, HERMES)
    k = int(np.flatnonzero(ss.stable)[0])
    assert end["granular_shear_stress_Pa"] == pytest.approx(float(ss.taubar[k]), rel=1e-6)
    assert end["f"] == pytest.approx(float(ss.f[k]), rel=1e-6)


@pytest.mark.parametrize("tau", [1.0, 10.0, 300.0])
def test_creep_ends_on_steady_state_in_dst_range(tau):
    """phi = 0.52 > phi_c: above ~3 Pa the steady rate falls as the stress rises (DST)."""
    phi = 0.52
    df = creep(HERMES, phi, tau, 1000.0, G=1e4, K0=1.0, rtol=1e-9)
    ss = rheology.steady_states_mixture_stress(tau, phi, HERMES)
    assert len(ss.shear_rate) == 1
    assert df["shear_rate_per_s"].iloc[-1] == pytest.approx(float(ss.shear_rate[0]), rel=1e-6)
    assert df["f"].iloc[-1] == pytest.approx(float(ss.f[0]), rel=1e-6)


def test_dae_and_ode_forms_and_jacobians_agree():
    out = []
    for form in ("dae", "ode"):
        for jac in (True, False):
            r = Rheometer(HERMES, 0.52, G=1e4, K0=1.0, rtol=1e-10, form=form, jacobian=jac)
            out.append(r.run([Step("rate", 0.0, duration=20.0)], r.steady(1e3), points=50))
    for df in out[1:]:
        assert np.allclose(df["shear_stress_Pa"], out[0]["shear_stress_Pa"], rtol=0, atol=1e-6)
        assert np.allclose(df["f"], out[0]["f"], rtol=0, atol=1e-9)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_exact_jacobian_matches_finite_differences(sign):
    """Also for a reversed (negative) stress and plastic rate and the sinusoidal controls."""
    rng = np.random.default_rng(1)
    P = model.parameters(HERMES, 0.52, 1e4, 2.0)
    for mode, kind in ((model.RATE, model.LOG), (model.STRESS, model.LOG),
                       (model.RATE, model.COSINE), (model.STRESS, model.SINE)):
        C = model.control(mode, kind, 0.1, 10.0, 0.0, 5.0)
        y = np.array([30.0 * sign, 0.004, 0.09 * sign, 0.2, 1.0]) * (1 + 0.1 * rng.random(5))
        yp = rng.normal(size=5)
        J = np.empty((5, 5))
        cj = 3.7
        model.jacobian(1.3, y, yp, cj, J, P, C)
        fd = np.empty((5, 5))
        r0, r1 = np.empty(5), np.empty(5)
        for j in range(5):
            h = 1e-7 * max(abs(y[j]), 1e-8)
            yh, ypp = y.copy(), yp.copy()
            yh[j] += h
            ypp[j] += cj * h
            model.residual(1.3, y, yp, r0, P, C)
            model.residual(1.3, yh, ypp, r1, P, C)
            fd[:, j] = (r1 - r0) / h
        assert np.allclose(J, fd, rtol=1e-5, atol=1e-6 * np.abs(J).max())


def test_unjamming_event_time_is_exact():
    """A jammed sample at rest (gdot_p = 0) loses structure by buckling only:
    f = f0 exp(-K0 taubar t/eta_B); it unjams when f = f_jam, an IDA root event."""
    m = rheology.get_material("singh2018_b")
    phi, tau0, f0, K0 = 0.62, 10.0, 0.6, 1.0
    r = Rheometer(m, phi, G=1e3, K0=K0, rtol=1e-10)
    df = r.run([Step("rate", 0.0, duration=10.0)], r.state(tau0, f0), points=100)
    inv_eta_b = 1.0 / float(rheology.eta_B(phi, m))
    f_jam = (m.phi_j - phi) / (m.phi_j - m.phi_c)
    t_star = np.log(f0 / f_jam) / (K0 * tau0 * inv_eta_b)
    (t_ev, step, what), = df.attrs["events"]
    assert what == "unjammed" and step == 1
    assert t_ev == pytest.approx(t_star, rel=1e-7)
    before = df[df["time_s"] < t_star]
    assert np.allclose(before["shear_stress_Pa"], tau0, rtol=1e-12)        # frozen while jammed
    assert df["shear_stress_Pa"].iloc[-1] < 0.5 * tau0                      # relaxes after


def test_strain_target_stops_the_step():
    r = Rheometer(HERMES, 0.50, G=1e4, K0=1.0)
    df = r.run([Step("rate", 2.0, strain=5.0), Step("rate", 0.0, duration=1.0)], points=50)
    first = df[df["step"] == 1]
    assert first["time_s"].iloc[-1] == pytest.approx(2.5, rel=1e-8)
    assert first["strain"].iloc[-1] == pytest.approx(5.0, rel=1e-8)
    assert ("strain reached" in [e[2] for e in df.attrs["events"]])
    assert df["time_s"].iloc[-1] == pytest.approx(3.5, rel=1e-8)


def test_approach_to_jamming_stays_unjammed_and_bounded():
    """singh2018_a has eta_B = inf: f creeps up to f_jam only asymptotically (gap ~ 1/t); with
    the gap as the state IDA follows it without stepping through jamming."""
    m = rheology.get_material("singh2018_a")
    df = startup(m, 0.60, 1.0, 50.0, G=1e3, K0=1.0)
    gap = df["jamming_gap"].to_numpy()
    assert df.attrs["events"] == []
    assert np.all(gap > 0) and gap[-1] < 1e-8
    assert np.all(np.diff(gap) <= 0)


def test_unphysical_solution_ends_the_run_before_it():
    r = Rheometer(HERMES, 0.52)

    class Sol:
        success, message, nfev = True, "Successful function return.", 10
        t = np.array([0.0, 1.0])

    y = np.zeros((2, 5))
    y[:, 1] = r.state(1.0, 0.1).gap
    y[1, 1] = r.state(1.0, 0.1).gap + 0.5          # f far below 0
    keep, end = r._check_solution(Sol(), y, Step("rate", 1.0, duration=1.0), 0,
                                  r.state(1.0, 0.1))
    assert keep == 1 and end.kind == "solver_failure" and end.time_s == 0.0
    assert "unphysical state" in end.reason and "at t = 1 s" in end.reason


@pytest.mark.parametrize("kwargs, match", [
    (dict(phi=0.6), "phi = 0.6 is outside"),
    (dict(phi=float("nan")), "phi = nan: must be finite"),
    (dict(G=-1.0), "G"),
    (dict(K0=-1.0), "K0"),
    (dict(rtol=1.0), "rtol"),
])
def test_bad_parameters_raise(kwargs, match):
    args = dict(material=HERMES, phi=0.5) | kwargs
    with pytest.raises(ValueError, match=match):
        Rheometer(args.pop("material"), args.pop("phi"), **args)


@pytest.mark.parametrize("step, match", [
    (dict(control="rate", start=-1.0, duration=1.0), "imposed rate"),
    (dict(control="flow", start=1.0, duration=1.0), "control"),
    (dict(control="rate", start=0.0, end=1.0, ramp="log", duration=1.0), "log ramp"),
    (dict(control="rate", start=1.0), "duration"),
    (dict(control="stress", start=1.0, duration=0.0), "duration"),
    (dict(control="strain", start=0.01, duration=1.0), "strain-controlled step is an oscill"),
    (dict(control="rate", start=1.0, ramp="sine", frequency=1.0, duration=1.0), "not a rate"),
    (dict(control="strain", start=0.01, ramp="sine", duration=1.0), "needs a frequency"),
    (dict(control="strain", start=0.0, ramp="sine", frequency=1.0, duration=1.0), "amplitude"),
    (dict(control="stress", start=1.0, ramp="sine", frequency=1.0, strain=1.0), "cycles"),
    (dict(control="rate", start=1.0, duration=1.0, frequency=2.0), "only an oscillation"),
])
def test_bad_steps_raise(step, match):
    with pytest.raises(ValueError, match=match):
        Step(**step)


def test_state_round_trip():
    r = Rheometer(HERMES, 0.52)
    st = r.state(3.0, 0.1234)
    assert isinstance(st, State)
    assert float(model.structure_of_gap(st.gap, r.P)) == pytest.approx(0.1234, rel=1e-13)


def test_signed_law_is_odd_and_unchanged_for_positive_stress():
    """gdot_p(-taubar) = -gdot_p(taubar), the structure rate even in taubar, and for taubar >= 0
    the signed law is the paper's magnitude law (Eq. 35) itself."""
    P = model.parameters(HERMES, 0.50, 1e4, 1.0)
    for tau in (1e-6, 0.3, 5.0, 300.0):
        for gap in (0.03, 0.004, -0.001):
            g = model.plastic_rate(tau, gap, P)
            assert model.signed_plastic_rate(tau, gap, P) == g
            assert model.signed_plastic_rate(-tau, gap, P) == -g
            assert model.signed_gap_rate(gap, -tau, -g, P) == model.gap_rate(gap, tau, g, P)


def test_stress_step_below_the_granular_stress_reverses_the_flow():
    """From a steady state at 10 Pa, an imposed mixture stress of 0: the fluid takes the
    granular stress at once, gdot = -taubar/eta_F (recoil), and the skeleton relaxes to zero
    through the reversed flow, never overshooting into a negative stress."""
    r = Rheometer(HERMES, 0.50, G=1e4, K0=1.0, rtol=1e-9)
    df = r.run([Step("stress", 0.0, duration=1.0)], r.steady(10.0), points=100)
    eta_F = HERMES.eta0 * (1 + 2.5 * 0.50)
    assert df["shear_rate_per_s"].iloc[0] == pytest.approx(-10.0 / eta_F, rel=1e-9)
    assert np.allclose(df["shear_stress_Pa"], 0.0, atol=1e-9)
    tau = df["granular_shear_stress_Pa"].to_numpy()
    assert np.all(np.diff(tau) <= 1e-12) and tau[-1] < 1e-6 and tau.min() > -1e-9
