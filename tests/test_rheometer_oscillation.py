"""Oscillatory shear of the 0-D model: the linear limit against the Maxwell-type G*(omega) derived
in rheometer.oscillation, the fluid-dominated high-frequency loss modulus, the harmonic analysis,
the periodic steady state, and the onset of strain stiffening at the DST stress."""

import numpy as np
import pytest

import rheology
from rheometer import oscillation as osc
from rheometer.cli import main as cli_main
from rheometer.limits import check_peak_rate
from rheometer.oscillation import oscillation_sweep

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


# ------------------------------------------------------------------ a point that fails
def _failing_at(monkeypatch, bad_amplitude):
    """A sweep's point (its inputs checked) as it is, except that the point at
    ``bad_amplitude`` fails as IDA does."""
    real = osc._point

    def point(m, phi, G, K0, frequency, amplitude, control, **kw):
        if amplitude == bad_amplitude:
            raise RuntimeError(f"IDA failed in oscillation at phi = {phi:g}, {frequency:g} Hz, "
                               f"strain amplitude {amplitude:g}, cycle 3, t = 2.5 s: "
                               "the corrector convergence failed repeatedly")
        return real(m, phi, G, K0, frequency, amplitude, control, **kw)

    monkeypatch.setattr(osc, "_point", point)


def test_a_failed_point_keeps_its_row_and_the_other_points(monkeypatch):
    amps = [0.001, 0.05, 0.3]
    ref, ref_w = osc.oscillation_sweep(HERMES, PHI, frequency=1.0, amplitude=amps)
    _failing_at(monkeypatch, 0.05)
    pts, waves = osc.oscillation_sweep(HERMES, PHI, frequency=1.0, amplitude=amps)
    assert len(pts) == 3 and list(pts["strain_amplitude"]) == amps
    bad = pts.iloc[1]
    assert "IDA failed" in bad["reason"] and not bad["converged"]
    for c in ("storage_modulus_Pa", "loss_modulus_Pa", "I3_over_I1", "max_elastic_strain"):
        assert np.isnan(bad[c])
    assert pd_isna(bad["cycles"])
    lin = osc.linear_modulus(HERMES, PHI, 1.0)             # defined for every point
    assert bad["linear_storage_modulus_Pa"] == pytest.approx(lin.real, rel=1e-14)
    for k in (0, 2):                          # the other points: as in the sweep without it
        assert pts["reason"].iloc[k] == ""
        assert pts["storage_modulus_Pa"].iloc[k] == ref["storage_modulus_Pa"].iloc[k]
    assert sorted(set(waves["point"])) == [0, 2]           # no waveform of the failed point
    (end,) = pts.attrs["ends"]
    assert end.kind == "solver_failure" and end.run == "phi = 0.5, 1 Hz, strain amplitude 0.05"


def pd_isna(x):
    import pandas as pd

    return bool(pd.isna(x))


def test_cli_failed_point_exit_3_with_its_row_and_reason(tmp_path, monkeypatch, capsys):
    import json

    import pandas as pd

    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    _failing_at(monkeypatch, 0.05)
    assert main(["oscillation", "--strain-amplitude", "0.001", "0.05", "0.3"]) == 3
    err = capsys.readouterr().err
    assert ("rheometer oscillation: phi = 0.5, 1 Hz, strain amplitude 0.05: ended early before "
            "its first row: IDA failed") in err
    pts = pd.read_csv("oscillation.csv", keep_default_na=False)
    assert len(pts) == 3 and pts["storage_modulus_Pa"].iloc[1] == ""      # empty cell
    assert pts["reason"].iloc[1].startswith("IDA failed") and pts["reason"].iloc[0] == ""
    assert float(pts["storage_modulus_Pa"].iloc[2]) > 100
    rec = json.loads((tmp_path / "oscillation.json").read_text())
    assert rec["status"] == "ended_early" and rec["failed_points"] == 1
    assert rec["ends"][0]["kind"] == "solver_failure"
    for name in ("oscillation.png", "oscillation_lissajous.png"):
        assert (tmp_path / name).stat().st_size > 10_000


def test_figures_mark_past_limit_and_failed_points_and_keep_legends_off_data(monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from figure_checks import assert_legends_clear_of_data
    from rheology.elastic import ELASTIC_STRAIN_LIMIT
    from rheometer import plots

    _failing_at(monkeypatch, 0.01)
    amps = list(np.logspace(-3, 0, 7))
    amps[2] = 0.01
    pts, waves = osc.oscillation_sweep(HERMES, PHI, frequency=1.0, amplitude=amps)
    dst = osc.dst_onset_stress(HERMES, PHI)
    past = pts["max_elastic_strain"] > ELASTIC_STRAIN_LIMIT
    assert 0 < past.sum() < len(pts) - 1
    fig = plots.oscillation_figure(pts, "sweep", dst)
    ax = fig.axes[0]
    hollow = [ln for ln in ax.get_lines() if isinstance(ln.get_markerfacecolor(), str)
              and ln.get_markerfacecolor() == "white" and ln.get_linestyle() == "None"]
    xs = sorted(float(x) for ln in hollow for x in ln.get_xdata())
    assert xs == sorted(2 * list(pts.loc[past, "strain_amplitude"]))       # G' and G''
    failed = [ln for ln in ax.get_lines() if ln.get_marker() == "X"]
    assert len(failed) == 1 and failed[0].get_xdata()[0] == 0.01
    assert "past the elastic-strain limit" in fig._suptitle.get_text()
    assert_legends_clear_of_data(fig)
    plt.close(fig)
    fig = plots.lissajous_figure(waves, "LB", points=pts, dst_stress=dst)
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    onset = float(pts.loc[pts["peak_stress_Pa"] >= dst, "strain_amplitude"].iloc[0])
    assert any(f"gamma0 = {onset:.3g}" in s and "thickening starts" in s for s in labels)
    # every entry names a visible curve: as many entries as drawn stress curves per panel
    assert len(labels) == len([ln for ln in fig.axes[0].get_lines()
                               if ln.get_linestyle() in ("-", "-.")]) - 2   # minus the axes
    assert_legends_clear_of_data(fig)
    plt.close(fig)


def test_a_strain_oscillation_past_the_rate_limit_is_refused(tmp_path, capsys):
    """2 pi f gamma0 is a shear rate: held to the 1e9 1/s of every imposed rate (1e9 Hz at
    gamma0 = 1 is 6.28e9 1/s and ran); one line, exit 2, nothing written."""
    with pytest.raises(ValueError, match=r"peak shear rate 2 pi f gamma0 at 1e\+09 Hz and strain "
                                         r"amplitude 1 = 6.28319e\+09 is outside the valid range "
                                         r"\[0, 1e\+09\] 1/s"):
        oscillation_sweep("hermes2016", 0.5, frequency=[1.0, 1e9], amplitude=1.0)
    assert check_peak_rate(1e8, 1.0) == pytest.approx(6.28319e8)
    out = tmp_path / "osc.csv"
    # (the default sweep ends at 0.1: 6.28e8 1/s at 1e9 Hz; amplitude 1 is past the limit)
    assert cli_main(["oscillation", "--frequency", "1e9", "--strain-amplitude", "1", "--phi",
                     "0.5", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "peak shear rate" in err[0] and not list(tmp_path.iterdir())
    prog = tmp_path / "prog.txt"
    prog.write_text("shear at 1 1/s for 1 s\noscillate at 1e9 Hz with strain 1 for 2 cycles\n")
    assert cli_main(["program", str(prog), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "program line 2: peak shear rate" in err[0] and not out.exists()


def test_the_help_default_sweep_stays_within_the_small_strain_limit(tmp_path, monkeypatch,
                                                                    capsys):
    """`rheometer oscillation` (the help's default: an amplitude sweep to 1 at 1 Hz) drove the
    default material to taubar/G = 0.99 (3 of 10 points past the limit 0.1, warned); the default
    sweep is now 1e-3..0.1, every point within the limit (run here on few cycles and samples)."""
    import pandas as pd

    from rheology.elastic import ELASTIC_STRAIN_LIMIT
    from rheometer.cli import main
    from rheometer.instrument_cli import STRAIN_AMPLITUDES

    lo, hi, n = STRAIN_AMPLITUDES
    with pytest.raises(SystemExit):
        main(["oscillation", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"Default: an amplitude sweep {lo:g}..{hi:g} at 1 Hz" in text
    assert f"default {n} values {lo:g}..{hi:g}" in text
    monkeypatch.chdir(tmp_path)
    assert main(["oscillation", "--cycles", "3", "--samples", "16", "--plot", "none"]) == 0
    out = capsys.readouterr().out
    pts = pd.read_csv("oscillation.csv")
    assert pts["strain_amplitude"].to_numpy() == pytest.approx(np.geomspace(lo, hi, n))
    assert (pts["max_elastic_strain"] <= ELASTIC_STRAIN_LIMIT).all(), pts["max_elastic_strain"]
    assert "past 0.1" not in out
