"""Test programs: the text format, its errors, and a run showing hysteresis."""

import numpy as np
import pytest

import rheology
from rheology.materials import default_fraction
from rheometer import HYSTERESIS_PROGRAM, Step, parse_program, run_program
from rheometer import oscillation as osc
from rheometer.program import dst_fold, hysteresis_program
from rheometer.transient import DEFAULT_MAX_TIME

HERMES = rheology.get_material("hermes2016")


def test_every_line_form_parses():
    prog = parse_program("""
        # a comment line
        start from steady stress 2 kPa
        shear at 10 1/s for 60 s          # trailing comment
        shear at 0.5 /s until strain 250%
        stress 5 Pa until strain 10 within 2 min
        Stress 300 mPa for 1.5 min
        rest for 100 ms
        ramp rate from 0.1 to 100 1/s over 60 s
        ramp stress from 1 to 3 kPa over 1 h linear
        """)
    assert prog.start.kind == "stress" and prog.start.value == 2000.0
    s = prog.steps
    assert (s[0].control, s[0].start, s[0].duration) == ("rate", 10.0, 60.0)
    assert (s[1].start, s[1].strain, s[1].duration, s[1].max_time) == (0.5, 2.5, None,
                                                                         DEFAULT_MAX_TIME)
    assert (s[2].control, s[2].start, s[2].strain, s[2].max_time) == ("stress", 5.0, 10.0, 120.0)
    assert (s[3].start, s[3].duration) == (0.3, 90.0)
    assert (s[4].control, s[4].start, s[4].duration) == ("rate", 0.0, 0.1)
    assert (s[5].ramp, s[5].start, s[5].end, s[5].duration) == ("log", 0.1, 100.0, 60.0)
    assert (s[6].control, s[6].ramp, s[6].start, s[6].end, s[6].duration) == (
        "stress", "linear", 1e3, 3e3, 3600.0)
    assert all(isinstance(x, Step) for x in s)


@pytest.mark.parametrize("text, match", [
    ("shear at 10 1/s for 60 s\nspin at 3 rpm", r"program line 2: unknown step 'spin'"),
    ("shear at 10 for 60 s", r"program line 1: cannot read .*expected 'shear at <rate> 1/s"),
    ("rest 100 s", r"program line 1: cannot read 'rest 100 s'; expected 'rest for <time> s'"),
    ("ramp rate from 0 to 10 1/s over 5 s", r"program line 1: a log ramp needs positive"),
    ("ramp rate from 1 to 10 Pa over 5 s", r"program line 1: a rate ramp needs 1/s"),
    ("stress 5 mpa for 1 s", r"program line 1: stress unit 'mpa' is ambiguous"),
    ("shear at 1 1/s for 1 s\nstart at rest", r"program line 2: 'start' must come before"),
    ("# nothing\n\n", r"the program has no steps"),
    ("shear at 1 1/s until strain 0", r"program line 1: step strain"),
])
def test_parse_errors_name_the_line_and_what_was_expected(text, match):
    with pytest.raises(ValueError, match=match):
        parse_program(text)


def test_builtin_program_shows_dst_and_hysteresis_at_the_default_phi():
    """The built-in program at hermes2016's default phi (0.50): the stress sweep crosses DST (the
    rate peaks at the steady curve's fold, then falls toward gdot_DST while the stress grows
    tenfold), the structure lags in both sweeps, and nothing jams (no 1e6 Pa)."""
    phi = default_fraction("hermes2016")
    assert phi == 0.50
    gd = float(rheology.gdot_dst(phi, HERMES))
    r_fold, s_fold = dst_fold(HERMES, phi)
    assert HYSTERESIS_PROGRAM == hysteresis_program(HERMES, phi)
    assert gd < r_fold < 2 * gd                           # 0.461 and 0.855 1/s
    df = run_program(HERMES, phi, HYSTERESIS_PROGRAM, points=200)
    assert df["step"].nunique() == 4
    assert df["shear_stress_Pa"].max() <= 10 * s_fold * 1.01      # 43 Pa, not 1e6
    f_jam = (HERMES.phi_j - phi) / (HERMES.phi_j - HERMES.phi_c)
    assert df["f"].max() < 0.9 * f_jam                    # flowing throughout
    up, down = df[df["step"] == 1], df[df["step"] == 2]
    # S-curve under stress control: the peak rate is the fold's (within the ramp's lag), and at
    # the top stress the rate has fallen to the steady value, between gdot_DST and the fold
    assert up["shear_rate_per_s"].max() == pytest.approx(r_fold, rel=0.1)
    top = up.iloc[-1]
    steady = rheology.steady_states_mixture_stress(top["shear_stress_Pa"], phi, HERMES)
    assert top["shear_rate_per_s"] == pytest.approx(float(steady.shear_rate[0]), rel=0.05)
    assert gd < top["shear_rate_per_s"] < 0.7 * up["shear_rate_per_s"].max()
    # on the way down (more structure) the rate at equal stress is lower
    stresses = np.geomspace(0.1, 30.0, 9)
    r_up = np.interp(np.log(stresses), np.log(up["shear_stress_Pa"]), up["shear_rate_per_s"])
    r_dn = np.interp(np.log(stresses), np.log(down["shear_stress_Pa"].to_numpy()[::-1]),
                     down["shear_rate_per_s"].to_numpy()[::-1])
    assert np.all(r_dn <= r_up) and np.max(r_up / r_dn) > 1.1       # measured 1.14
    # rate sweep below the fold: on the way down the stress at equal rate is higher
    up, down = df[df["step"] == 3], df[df["step"] == 4]
    rates = np.geomspace(0.05, 0.75, 9)
    order = np.argsort(down["shear_rate_per_s"].to_numpy())
    s_up = np.interp(np.log(rates), np.log(up["shear_rate_per_s"]), up["shear_stress_Pa"])
    s_down = np.interp(np.log(rates), np.log(down["shear_rate_per_s"].to_numpy()[order]),
                       down["shear_stress_Pa"].to_numpy()[order])
    assert np.all(s_down >= s_up * (1 - 1e-9)) and np.max(s_down / s_up) > 1.1


def test_builtin_program_without_dst_is_a_rate_sweep():
    text = hysteresis_program("hermes2016", 0.40)              # below phi_c: no fold
    assert dst_fold("hermes2016", 0.40) is None
    steps = parse_program(text).steps
    assert [s.control for s in steps] == ["rate", "rate"]


def test_program_from_steady_start_and_strain_step():
    df = run_program("hermes2016", 0.50, "start from steady rate 0.2 1/s\n"
                     "shear at 0.2 1/s until strain 4\nrest for 1 s", G=1e4, K0=1.0)
    first = df[df["step"] == 1]
    assert first["granular_shear_stress_Pa"].std() < 1e-6 * first["granular_shear_stress_Pa"].mean()
    assert first["time_s"].iloc[-1] == pytest.approx(20.0, rel=1e-8)
    assert df.attrs["start"].startswith("rate")


def test_start_from_rate_above_dst_is_refused():
    with pytest.raises(ValueError, match="no stable steady state"):
        run_program("hermes2016", 0.52, "start from steady rate 5 1/s\nrest for 1 s")


# ------------------------------------------------------------------ oscillation steps
def test_oscillation_lines_parse():
    s = parse_program("oscillate at 1 Hz with strain 0.01 for 10 cycles\n"
                      "oscillate at 500 mHz with stress 2 kPa for 3 cycles\n"
                      "Oscillate at 2 hz with strain 1% for 1 min\n"
                      "oscillate at 1 kHz with stress 300 mPa for 1 cycle").steps
    assert (s[0].control, s[0].ramp, s[0].start, s[0].frequency, s[0].cycles) == (
        "strain", "sine", 0.01, 1.0, 10.0)
    assert (s[1].control, s[1].start, s[1].frequency, s[1].duration) == ("stress", 2e3, 0.5, 6.0)
    assert (s[2].start, s[2].duration) == (0.01, 60.0) and s[2].cycles == pytest.approx(120.0)
    assert (s[3].start, s[3].frequency, s[3].cycles) == (0.3, 1e3, 1.0)


@pytest.mark.parametrize("text, match", [
    ("oscillate at 1 Hz with strain 0.01 Pa for 10 cycles", r"line 1: a strain amplitude is plain"),
    ("oscillate at 1 Hz with stress 2 for 10 cycles", r"line 1: a stress amplitude needs Pa"),
    ("oscillate at 1 MHZ with strain 0.01 for 10 cycles", r"line 1: frequency unit 'MHZ'"),
    ("oscillate at 0 Hz with strain 0.01 for 10 cycles", r"line 1: oscillation frequency"),
    ("oscillate at 1 Hz with strain 0 for 10 cycles",
     # was (0, 1e+06] (an arithmetic bottom 0): now STRAIN_MIN with its reason
     r"line 1: strain amplitude = 0 is outside the valid range \[1e-09, 1e\+06\] \(a "
     r"displacement of a molecular size"),
    ("oscillate at 1 Hz with strain 0.01 for 0 cycles",
     r"line 1: cycles = 0 is outside the valid range \(0, 100000\]"),
    ("oscillate at 1 Hz with strain 0.01 for 1e9 cycles", r"line 1: cycles = 1e\+09 is outside"),
    ("shear at 1e20 1/s for 1 s",
     r"line 1: imposed rate of 'shear at 1e20 1/s for 1 s' = 1e\+20 is outside the valid range "
     r"\[1e-09, 1e\+09\] 1/s, or 0 \(past"),
    ("oscillate at 1e400 Hz with strain 0.01 for 10 cycles",
     r"line 1: oscillation frequency = inf: must be finite; valid range \[1e-09, 1e\+09\] Hz"),
    ("shear at 1 1/s for 1e20 s", r"line 1: duration = 1e\+20 is outside"),
    ("start from steady stress 1e13 Pa\nrest for 1 s", r"line 1: stress = 1e\+13 is outside"),
    ("oscillate at 1 Hz with strain 0.01", r"line 1: cannot read .*expected 'oscillate at <F>"),
])
def test_oscillation_parse_errors(text, match):
    with pytest.raises(ValueError, match=match):
        parse_program(text)


def _last_cycle(df, step, freq):
    """Rows of the last full cycle of an oscillation step (equal phases from the step start)."""
    d = df[df["step"] == step]
    t0, t1 = d["time_s"].iloc[0], d["time_s"].iloc[-1]
    return d[d["time_s"] >= t1 - 1.0 / freq * (1 + 1e-9)].iloc[:-1], t0


def test_small_strain_oscillation_follows_the_linear_modulus():
    """G = 10 Pa: relaxation time eta_g/G ~ 0.2 s, so at 1 Hz G' and G'' are comparable and the
    start-up transient (from rest) dies within a few cycles; the last of ten cycles is the
    linear response sigma = Re[G* gamma0 (-i) e^(i omega t')] of rheometer.oscillation's G*."""
    G, A, F = 10.0, 1e-5, 1.0
    Glin = complex(osc.linear_modulus(HERMES, 0.50, F, G=G))
    assert 0.3 < Glin.real / Glin.imag < 3
    df = run_program(HERMES, 0.50, f"oscillate at {F:g} Hz with strain {A:g} for 10 cycles",
                     G=G, K0=1.0, rtol=1e-9)
    cyc, t0 = _last_cycle(df, 1, F)
    w = 2 * np.pi * F
    phase = w * (cyc["time_s"].to_numpy() - t0)
    assert np.allclose(cyc["strain"], A * np.sin(phase), rtol=0, atol=1e-7 * A)   # 2e-9
    linear = (Glin * A * -1j * np.exp(1j * phase)).real
    assert np.max(np.abs(cyc["shear_stress_Pa"] - linear)) < 1e-4 * abs(Glin) * A
    (res,) = df.attrs["oscillations"]
    Gs = complex(res["storage_modulus_Pa"], res["loss_modulus_Pa"])
    assert abs(Gs / Glin - 1) < 1e-4
    assert res["I3_over_I1"] < 1e-5 and res["cycle_change"] < 1e-6
    assert res["strain_amplitude"] == A


def test_small_stress_oscillation_strain_amplitude_is_stress_over_modulus():
    G, F = 10.0, 1.0
    Glin = complex(osc.linear_modulus(HERMES, 0.50, F, G=G))
    S = 1e-5 * abs(Glin)
    df = run_program(HERMES, 0.50, f"oscillate at {F:g} Hz with stress {S!r} Pa for 10 cycles",
                     G=G, K0=1.0, rtol=1e-9)
    (res,) = df.attrs["oscillations"]
    assert res["strain_amplitude"] == pytest.approx(S / abs(Glin), rel=1e-4)
    Gs = complex(res["storage_modulus_Pa"], res["loss_modulus_Pa"])
    assert abs(Gs / Glin - 1) < 1e-4
    cyc, t0 = _last_cycle(df, 1, F)
    phase = 2 * np.pi * F * (cyc["time_s"].to_numpy() - t0)
    assert np.allclose(cyc["shear_stress_Pa"], S * np.sin(phase), rtol=0, atol=1e-7 * S)


def test_oscillation_after_steady_shear_starts_from_that_state():
    """Continuity: the granular stress, f and the strain carry over exactly; the mixture stress
    jumps only by the fluid's share eta_F (rate jump) as the imposed rate changes."""
    A, F = 0.01, 1.0
    text = f"shear at 0.2 1/s for 30 s\noscillate at {F:g} Hz with strain {A:g} for 3 cycles"
    df = run_program(HERMES, 0.50, text, G=1e4, K0=1.0)
    before, after = df[df["step"] == 1].iloc[-1], df[df["step"] == 2].iloc[0]
    for col in ("time_s", "granular_shear_stress_Pa", "f", "strain", "jamming_gap"):
        assert after[col] == before[col], col
    eta_F = HERMES.eta0 * (1 + 2.5 * 0.50)
    assert after["shear_rate_per_s"] == pytest.approx(A * 2 * np.pi * F, rel=1e-12)
    assert after["shear_stress_Pa"] - before["shear_stress_Pa"] == pytest.approx(
        eta_F * (A * 2 * np.pi * F - 0.2), rel=1e-9)
    osc_rows = df[df["step"] == 2]
    assert np.allclose(osc_rows["strain"] - before["strain"],
                       A * np.sin(2 * np.pi * F * (osc_rows["time_s"] - before["time_s"])),
                       rtol=0, atol=1e-6)              # rtol 1e-7 of the strain (6) carried
    # from a steady stress: the first oscillation row is that steady state
    df = run_program(HERMES, 0.50, "start from steady stress 10 Pa\n"
                     "oscillate at 1 Hz with stress 5 Pa for 2 cycles", G=1e4, K0=1.0)
    first = df.iloc[0]
    steady = rheology.steady_state_stress(10.0, 0.50, HERMES)
    assert first["granular_shear_stress_Pa"] == 10.0
    assert first["f"] == pytest.approx(float(steady.f), rel=1e-12)
    assert first["shear_stress_Pa"] == pytest.approx(0.0, abs=1e-12)   # 5 sin(0) imposed


def test_large_oscillation_reverses_the_plastic_flow_and_matches_the_subcommand():
    """Beyond the linear range the stress reverses every half cycle; the plastic rate follows its
    sign (the clipped law would leave the negative half elastic and let the mean stress drift).
    At the periodic state the cycle is odd (sigma(t + T/2) = -sigma(t)) and its moduli equal
    those of rheometer.oscillation (the same residual, in its eliminated form)."""
    F, A = 1.0, 0.1
    df = run_program(HERMES, 0.50, f"oscillate at {F:g} Hz with strain {A:g} for 40 cycles",
                     G=1e4, K0=1.0, rtol=1e-8)
    tau, gp = df["granular_shear_stress_Pa"], df["plastic_shear_rate_per_s"]
    assert tau.min() < -0.5 * tau.max() < 0 and gp.min() < 0 < gp.max()
    assert np.all(gp * np.sign(tau) >= -1e-12 * gp.abs().max())
    cyc, _ = _last_cycle(df, 1, F)
    s = cyc["shear_stress_Pa"].to_numpy()
    n = s.size
    assert np.max(np.abs(s[: n // 2] + s[n // 2:])) < 1e-3 * np.abs(s).max()
    (res,) = df.attrs["oscillations"]
    point, _, _ = osc.oscillate(HERMES, 0.50, F, A, G=1e4, K0=1.0, rtol=1e-8, tol=1e-7)
    Gs = complex(res["storage_modulus_Pa"], res["loss_modulus_Pa"])
    Gp = complex(point["storage_modulus_Pa"], point["loss_modulus_Pa"])
    assert res["cycle_change"] < 1e-6                     # periodic after 40 cycles
    assert abs(Gs / Gp - 1) < 1e-5
    assert res["I3_over_I1"] == pytest.approx(point["I3_over_I1"], rel=1e-3)


def test_program_with_oscillation_resumes_between_steps(tmp_path):
    """A checkpoint after the oscillation step (through the checkpoint file) resumes to the same
    rows as the uninterrupted run, and the oscillation's analysis is recomputed identically."""
    from rheometer.checkpoint import ProgramCheckpoint

    text = ("start from steady stress 10 Pa\noscillate at 2 Hz with strain 0.02 for 4 cycles\n"
            "shear at 0.3 1/s for 5 s\noscillate at 1 Hz with stress 1 Pa for 2 cycles\n")
    prog = parse_program(text)
    opts = dict(G=1e4, K0=1.0, rtol=1e-7, points=100)
    seen = []
    full = run_program(HERMES, 0.50, prog, on_step=seen.append, **opts)
    ck = ProgramCheckpoint(tmp_path / "p.checkpoint.npz", HERMES, [0.50], text, opts)
    ck.progress = seen[1]                                   # after steps 1 and 2
    ck.save()
    ck2 = ProgramCheckpoint(tmp_path / "p.checkpoint.npz", HERMES, [0.50], text, opts)
    ck2.load()
    assert ck2.progress.next_step == 2
    resumed = ck2.run(prog)
    assert resumed.drop(columns="phi").equals(full)
    assert resumed.attrs["oscillations"] == full.attrs["oscillations"]
    assert [o["step"] for o in full.attrs["oscillations"]] == [1, 3]


def test_program_figure_shows_the_oscillation():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rheometer import plots

    df = run_program(HERMES, 0.50, "shear at 0.2 1/s for 10 s\n"
                     "oscillate at 1 Hz with strain 0.05 for 5 cycles\nrest for 2 s", points=100)
    fig = plots.program_figure(df, "program")
    _, ax_s, ax_r, _ = fig.axes
    osc_rows = df[df["step"] == 2]
    for ax, col in ((ax_s, "shear_stress_Pa"), (ax_r, "shear_rate_per_s")):
        (line,) = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
        x, y = (np.asarray(v, dtype=float) for v in line.get_data())
        on = (x >= osc_rows["time_s"].min()) & (x <= osc_rows["time_s"].max())
        assert on.sum() >= len(osc_rows) and y[on].min() < 0 < y[on].max()
        lo, hi = ax.get_ylim()
        assert lo <= osc_rows[col].min() and hi >= osc_rows[col].max()
    plt.close(fig)
