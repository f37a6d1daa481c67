"""Oscillatory shear of the 0-D model: the linear limit against the Maxwell-type G*(omega) derived
in rheometer.oscillation, the fluid-dominated high-frequency loss modulus, the harmonic analysis,
the periodic steady state, and the onset of strain stiffening at the DST stress."""

import numpy as np
import pytest

import rheology
from rheometer import oscillation as osc

HERMES = rheology.get_material("hermes2016")
PHI = 0.50


def _gstar(point):
    return complex(point["storage_modulus_Pa"], point["loss_modulus_Pa"])


def test_maxwell_parameters_from_the_laws():
    mx = osc.maxwell(HERMES, PHI)
    assert mx.G == 1e4                                          # transient default
    assert mx.eta_F == pytest.approx(HERMES.eta0 * (1 + 2.5 * PHI), rel=1e-15)
    eta_r_low = float(rheology.viscosity_low_limit(PHI, HERMES))     # Eq. (24)
    assert (mx.eta_g + mx.eta_F) / HERMES.eta0 == pytest.approx(eta_r_low, rel=1e-13)
    w = np.array([1e-3, 1.0, 1e3, 1e9])
    G = mx.modulus(w)
    lam = mx.relaxation_time
    assert np.allclose(G.real, mx.G * (w * lam) ** 2 / (1 + (w * lam) ** 2), rtol=1e-13)
    assert np.allclose(G.imag, mx.G * w * lam / (1 + (w * lam) ** 2) + w * mx.eta_F, rtol=1e-13)


@pytest.mark.parametrize("control", ["strain", "stress"])
@pytest.mark.parametrize("freq", [1.0, None, 1e4])
def test_small_amplitude_equals_linearised_modulus(control, freq):
    mx = osc.maxwell(HERMES, PHI)
    if freq is None:                                 # omega lambda = 1: G' and G'' comparable
        freq = 1.0 / (2 * np.pi * mx.relaxation_time)
    Glin = complex(osc.linear_modulus(HERMES, PHI, freq))
    amp = 1e-7 if control == "strain" else 1e-7 * abs(Glin)
    point, wave, _ = osc.oscillate(HERMES, PHI, freq, amp, control=control, rtol=1e-10, tol=1e-8)
    G = _gstar(point)
    assert point["converged"]
    assert abs(G - Glin) / abs(Glin) < 1e-4
    if freq < 1e3:                                   # both parts resolved where they are of size
        assert abs(G.imag / Glin.imag - 1) < 1e-4
    if abs(Glin.real) > 0.1 * abs(Glin):
        assert abs(G.real / Glin.real - 1) < 1e-4
    assert point["I3_over_I1"] < 1e-6                # linear: no third harmonic
    assert len(wave) == osc.DEFAULT_SAMPLES


def test_high_frequency_loss_modulus_is_the_fluids():
    mx = osc.maxwell(HERMES, PHI)
    eta_F = HERMES.eta0 * (1 + 2.5 * PHI)
    excess = []
    for f in (1e6, 1e7):
        w = 2 * np.pi * f
        point, _, _ = osc.oscillate(HERMES, PHI, f, 1e-7, rtol=1e-10, tol=1e-8)
        ratio = point["loss_modulus_Pa"] / (w * eta_F)
        excess.append(ratio - 1)
        # the analytic excess G^2/(omega^2 eta_g eta_F) of the Maxwell element
        assert ratio - 1 == pytest.approx(mx.G ** 2 / (w ** 2 * mx.eta_g * eta_F), rel=2e-2,
                                          abs=2e-6)
    assert excess[1] < 1e-5 and excess[1] < excess[0]   # -> omega eta0 (1 + 5/2 phi)


def test_harmonics_and_elastic_viscous_stresses_exact():
    N = 64
    ph = 2 * np.pi * np.arange(N) / N
    s = 3.0 * np.sin(ph) + 2.0 * np.cos(ph) + 0.1 * np.sin(3 * ph)
    c = osc.harmonics(s)
    assert c[0] == pytest.approx(2.0 - 3.0j, abs=1e-13)
    assert c[1] == pytest.approx(-0.1j, abs=1e-13)
    el, vi = osc.elastic_viscous(s)
    assert np.allclose(el, 3.0 * np.sin(ph) + 0.1 * np.sin(3 * ph), atol=1e-13)
    assert np.allclose(vi, 2.0 * np.cos(ph), atol=1e-13)


def test_periodic_state_repeats_itself():
    p1, w1, end = osc.oscillate(HERMES, PHI, 1.0, 0.1)
    assert p1["converged"] and p1["cycle_change"] < osc.DEFAULT_TOL
    # three more cycles from the final state: the same cycle within the tolerance
    p2, w2, _ = osc.oscillate(HERMES, PHI, 1.0, 0.1, state=end, max_cycles=3, min_cycles=3,
                              fixed_cycles=True)
    scale = np.abs(w1["shear_stress_Pa"]).max()
    assert np.max(np.abs(w2["shear_stress_Pa"].to_numpy() - w1["shear_stress_Pa"].to_numpy())) \
        < 20 * osc.DEFAULT_TOL * scale
    assert _gstar(p2) == pytest.approx(_gstar(p1), rel=20 * osc.DEFAULT_TOL)


def test_strain_stiffening_where_peak_stress_crosses_dst_stress():
    sigma_dst = osc.dst_onset_stress(HERMES, PHI)
    steady = rheology.steady_state_stress(np.logspace(-2, 2, 400), PHI, HERMES)
    assert 1.0 < sigma_dst < 10.0 and sigma_dst < steady.shear_stress.max()
    amps = np.array([0.01, 0.05, 0.1, 0.15, 0.2, 0.3])
    pts, _ = osc.oscillation_sweep(HERMES, PHI, frequency=1.0, amplitude=amps)
    assert pts["converged"].all()
    over = pts["peak_stress_Pa"].to_numpy() >= sigma_dst
    k = int(np.argmax(over))                       # first amplitude past the DST stress
    assert over.any() and k > 0 and over[k:].all()
    i3 = pts["I3_over_I1"].to_numpy()
    g1 = pts["storage_modulus_Pa"].to_numpy()
    assert np.all(i3[:k] < 1e-2)                  # below: nearly linear
    assert np.all(np.diff(i3[:k]) > 0)             # I3/I1 rising toward the onset
    assert i3[k] > 5 * i3[k - 1] and i3[k] > 0.02   # the onset: a jump in the third harmonic
    assert g1[k] > 100 * g1[k - 1]                  # strain stiffening (jammed, elastic)
    assert pts["mean_f"].iloc[k] > 0.9 * (HERMES.phi_j - PHI) / (HERMES.phi_j - HERMES.phi_c)


def test_bad_input_names_the_parameter():
    with pytest.raises(ValueError, match="frequency"):
        osc.oscillate(HERMES, PHI, -1.0, 0.01)
    with pytest.raises(ValueError, match="control"):
        osc.oscillate(HERMES, PHI, 1.0, 0.01, control="rate")
    with pytest.raises(ValueError, match="phi"):
        osc.oscillate(HERMES, 0.6, 1.0, 0.01)
    with pytest.raises(ValueError, match="samples"):
        osc.oscillate(HERMES, PHI, 1.0, 0.01, samples=4)


def test_cli_oscillation_sweep_with_geometry(tmp_path, monkeypatch, capsys):
    import pandas as pd

    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["oscillation", "--strain-amplitude", "0.001", "0.1", "--frequency", "1",
                 "--geometry", "cone-plate"]) == 0
    out = capsys.readouterr().out
    assert "periodic steady state" in out and "2/2 points" in out
    pts = pd.read_csv("oscillation.csv")
    waves = pd.read_csv("oscillation_waveforms.csv")
    for name in ("oscillation.png", "oscillation_lissajous.png"):
        assert (tmp_path / name).stat().st_size > 10_000
    assert len(pts) == 2 and len(waves) == 2 * osc.DEFAULT_SAMPLES
    assert {"storage_modulus_Pa", "loss_modulus_Pa", "complex_viscosity_Pa_s", "I3_over_I1",
            "cycles", "torque_amplitude_N_m"} <= set(pts.columns)
    assert {"elastic_stress_Pa", "viscous_stress_Pa", "torque_N_m"} <= set(waves.columns)
    G = pts["storage_modulus_Pa"] + 1j * pts["loss_modulus_Pa"]
    assert np.allclose(pts["complex_viscosity_Pa_s"], np.abs(G) / (2 * np.pi), rtol=1e-12)
    assert pts["phi"].iloc[0] == 0.50                     # the material's default


def test_cli_oscillation_normalised_material(tmp_path, monkeypatch):
    import pandas as pd

    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["oscillation", "--material", "singh2018_a", "--strain-amplitude", "0.01",
                 "--control", "strain", "--plot", "none"]) == 0
    pts = pd.read_csv("oscillation.csv")
    assert "storage_modulus_eta0_gdot0" in pts.columns and "frequency_gdot0" in pts.columns
    assert not any(c.endswith("_Pa") for c in pts.columns)


def test_points_past_the_small_strain_limit_are_flagged(tmp_path, monkeypatch, capsys):
    """Issue 15's amplitude sweep deliberately drives the jammed sample to elastic strains ~1
    (strain stiffening); the hypoelastic law is then outside its small-strain range
    (rheology.elastic): each point reports max_elastic_strain = max |taubar|/G over the cycle,
    and the command warns, naming the points past 0.1."""
    import pandas as pd

    from rheology.elastic import ELASTIC_STRAIN_LIMIT
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["oscillation", "--strain-amplitude", "0.01", "1", "--plot", "none"]) == 0
    out = capsys.readouterr().out
    pts = pd.read_csv("oscillation.csv")
    waves = pd.read_csv("oscillation_waveforms.csv")
    for k, row in pts.iterrows():
        tb = waves[waves["point"] == k]["granular_shear_stress_Pa"].abs().max()
        assert row["max_elastic_strain"] == pytest.approx(tb / 1e4, rel=1e-12)
    assert pts["max_elastic_strain"].iloc[0] < 1e-3 < ELASTIC_STRAIN_LIMIT
    assert pts["max_elastic_strain"].iloc[1] > 0.5
    assert "WARNING: 1/2 points strain the skeleton elastically past 0.1" in out
