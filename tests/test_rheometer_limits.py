"""Input limits of the rheometer that a fresh user found missing (rheometer.limits): durations
below what the model and IDA's clock resolve, tiny flow-curve ranges, --set parameters."""

import os

import numpy as np
import pytest

from rheometer import Step, parse_program
from rheometer import limits
from rheometer.cli import main
from rheometer.transient import Rheometer


def _refused(capsys, argv, *words):
    try:                          # argparse exits, a later check returns the status
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    err = capsys.readouterr().err.strip()
    assert rc == 2, err
    assert len(err.splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


@pytest.mark.parametrize("argv", [
    ["startup", "--rate", "0.5", "--t-end", "1e-300"],
    ["creep", "--stress", "10", "--t-end", "1e-13"],
    ["relax", "--stress", "10", "--t-end", "1e-300"],
    ["material-point", "--t-end", "1e-300"],
    ["material-point", "--dt", "1e-300"],
])
def test_durations_below_a_picosecond_are_refused_before_the_solver(argv, tmp_path, monkeypatch,
                                                                    capsys):
    """Before: IDA failed ('tstop = 1e-300 is behind current t = 0', exit 1)."""
    monkeypatch.chdir(tmp_path)
    _refused(capsys, argv, argv[-2], "[1e-12, 1e+09] s")
    assert os.listdir(tmp_path) == []


def test_the_shortest_duration_runs(tmp_path, monkeypatch, capsys):
    """--t-end = TIME_MIN integrates: start-up at rate r from rest loads the skeleton
    elastically, taubar <= G r t (= 5e-9 Pa at G = 1e4 Pa, r = 0.5 1/s, t = 1e-12 s)."""
    monkeypatch.chdir(tmp_path)
    main(["startup", "--rate", "0.5", "--t-end", "1e-12", "--plot", "none", "--out", "s.csv"])
    import pandas as pd
    df = pd.read_csv(tmp_path / "s.csv")
    assert df["time_s"].iloc[-1] == pytest.approx(1e-12, rel=1e-12)
    tau = df["granular_shear_stress_Pa"].to_numpy()
    assert np.all(np.isfinite(tau)) and np.all(tau >= 0) and tau[-1] <= 1e4 * 0.5 * 1e-12 * 1.001


def test_program_step_durations_checked_against_the_clock():
    """Before: 'rest for 1e-300 s' reached IDA (exit 1); 'rest for 1e-6 s' after 1e6 s gave
    "'tspan' must stictly increase" (an output grid the clock could not resolve)."""
    with pytest.raises(ValueError, match=r"program line 1: duration = 1e-300 .*\[1e-12, 1e\+09\]"):
        parse_program("rest for 1e-300 s")
    with pytest.raises(ValueError, match=r"program line 2: duration = 1e-06 is outside the "
                                         r"valid range \[0.001, 1e\+09\] s \(too short for "
                                         r"the run's clock"):
        parse_program("shear at 0.01 1/s for 1e6 s\nrest for 1e-6 s")
    prog = parse_program("shear at 0.01 1/s for 1e6 s\nrest for 1e-3 s")
    assert prog.steps[1].duration == pytest.approx(limits.clock_floor(1e6))


def test_a_step_the_clock_cannot_resolve_after_a_strain_step_fails_with_diagnostics():
    """A strain-ended step's length is known only when it ran: the run checks again."""
    rh = Rheometer("hermes2016", 0.40)
    steps = [Step("rate", 1.0, duration=2e4), Step("rate", 0.0, duration=1e-9)]
    with pytest.raises(RuntimeError, match=r"step 2 .* too short for the run's clock at t = 20000"):
        rh.run(steps, points=5)


@pytest.mark.parametrize("argv, option, shown", [
    (["--control", "rate", "--rate-range", "1e-300", "1"], "--rate-range", "[1e-09, 1e+09] 1/s"),
    (["--control", "rate", "--rate-range", "1e-200", "1"], "--rate-range", "[1e-09, 1e+09] 1/s"),
    (["--stress-range", "1e-300", "1"], "--stress-range", "[1e-12, 1e+12] Pa"),
    (["--control", "mixture-stress", "--stress-range", "1e-13", "1"], "--stress-range",
     "[1e-12, 1e+12] Pa"),
])
def test_flow_curve_range_below_its_floor_is_refused_at_once(argv, option, shown, tmp_path,
                                                              monkeypatch, capsys):
    """Before: --rate-range 1e-300 1 was refused after 77 s naming 'taubar' (the steady solver's
    bracketing grid spans every decade down to the rate), 1e-200 ran for minutes; now argparse
    refuses it, the steady solvers are never called."""
    import rheology

    def never(*a, **k):
        raise AssertionError("the steady solver was called")
    for name in ("steady_states_rate", "steady_states_mixture_stress", "steady_state_stress"):
        monkeypatch.setattr(rheology, name, never)
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["flow-curve", *argv], option, shown)
    assert os.listdir(tmp_path) == []


def test_flow_curve_at_the_lowest_rate_is_the_newtonian_plateau(tmp_path, monkeypatch):
    """At RATE_MIN the steady state exists and is the low-rate Newtonian limit: the viscosity is
    the same at 1e-9 and 1e-8 1/s, and stress = viscosity x rate."""
    import pandas as pd
    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve", "--control", "rate", "--rate-range", "1e-9", "1e-8", "--phi",
                 "0.3", "--points", "3", "--plot", "none", "--out", "fc.csv"]) == 0
    df = pd.read_csv("fc.csv")
    assert len(df) == 3 and df["shear_rate_per_s"].iloc[0] == pytest.approx(1e-9, rel=1e-9)
    eta = df["viscosity_Pa_s"].to_numpy()
    assert np.ptp(eta) <= 1e-6 * eta[0]
    assert np.allclose(df["shear_stress_Pa"], eta * df["shear_rate_per_s"], rtol=1e-9)


@pytest.mark.parametrize("cmd", ["flow-curve", "startup", "creep", "relax", "program",
                                 "material-point", "oscillation", "materials"])
@pytest.mark.parametrize("item, words", [
    ("tau_star=1e-300", "--set tau_star = 1e-300 is outside the valid range [1e-08, 1e+08] Pa"),
    ("eta0=1e-300", "--set eta0 = 1e-300 is outside the valid range [1e-05, 1e+06] Pa s"),
    ("phi_j=0.4", "--set phi_j = 0.4 is outside the valid range (0.436, 1)"),
    ("a0=1e300", "--set a0 = 1e+300 is outside the valid range (0, 0.8]"),
])
def test_every_command_names_the_set_parameter_with_its_range(cmd, item, words, tmp_path,
                                                              monkeypatch, capsys):
    """Before: flow-curve --set tau_star=1e-300 -> 'taubar = 0.001 is outside the valid range
    [0, 1e-200]' (neither tau_star nor a range of it); startup --set eta0=1e-300 failed on a
    CSV with NaN pressures (exit 1)."""
    monkeypatch.chdir(tmp_path)
    extra = ["--material", "hermes2016"] if cmd == "materials" else []
    _refused(capsys, [cmd, *extra, "--set", item], words)
    assert os.listdir(tmp_path) == []


def test_set_scales_at_their_bounds_give_the_scaled_flow_curve():
    """tau* at both ends of its range: the stress-controlled curve is self-similar in
    taubar/tau* (Eqs. 1-2 depend on the stress only through it), so the viscosity at
    taubar = x tau* is the same function of x at tau* = 1e-8 and 1e8 Pa."""
    from rheometer.options import material_with
    from rheometer.protocols import flow_curve

    x = np.logspace(-3, 3, 7)
    eta = [flow_curve(material_with("hermes2016", {"tau_star": t}), 0.45,
                      stress=x * t)["viscosity_Pa_s"].to_numpy() for t in (1e-8, 1e8)]
    assert np.allclose(eta[0], eta[1], rtol=1e-9)


def test_fit_set_is_checked_against_the_same_ranges(tmp_path, capsys):
    from pathlib import Path
    ex = Path(__file__).resolve().parents[1] / "rheometer" / "examples"
    out = tmp_path / "fit"
    _refused(capsys, ["fit", str(ex / "rheocompass_phi_0.40.csv"), "--phi", "0.40", "--out",
                      str(out), "--set", "tau_star=1e-300"],
             "--set tau_star = 1e-300 is outside the valid range [1e-08, 1e+08] Pa")
    assert not out.exists()


def test_oscillation_period_within_the_longest_duration(tmp_path, monkeypatch, capsys):
    """--frequency 1e-300 Hz (a period of 1e300 s, past TIME_MAX) ran; now refused by name."""
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["oscillation", "--frequency", "1e-300"], "--frequency = 1e-300",
             "[1e-09, 1e+09] Hz")
    with pytest.raises(ValueError, match=r"oscillation frequency = 1e\+300 is outside the valid "
                                         r"range \[1e-09, 1e\+09\] Hz \(a period of 1 ns"):
        parse_program("oscillate at 1e300 Hz with strain 0.01 for 10 cycles")
    assert os.listdir(tmp_path) == []


def test_flow_curve_rows_hold_the_rate_limit(tmp_path, monkeypatch, capsys):
    """Before: --phi 1e-10 wrote 200 rows at rates up to 1e25 1/s (exit 0). Now 1e-10 is below
    the dilute limit PHI_MIN = 1e-6 (a physical bound, refused as such); at 1e-6 every steady
    state flows past the rate limit."""
    import pandas as pd
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["flow-curve", "--phi", "1e-10"], "--phi = 1e-10 is outside the valid "
             "range [1e-06, 0.535) (one grain volume in 1e6")
    _refused(capsys, ["flow-curve", "--phi", "1e-6"], "--phi 1e-06",
             "faster than the largest shear rate 1e+09 1/s")
    assert os.listdir(tmp_path) == []
    assert main(["flow-curve", "--phi", "1e-4", "--plot", "none", "--out", "fc.csv"]) == 0
    assert "steady states flow faster than the largest shear rate" in capsys.readouterr().out
    assert pd.read_csv("fc.csv")["shear_rate_per_s"].max() <= limits.RATE_MAX


def test_creep_stress_the_liquid_would_carry_past_the_rate_limit_is_refused(tmp_path,
                                                                             monkeypatch, capsys):
    """Before: creep at 1e12 Pa wrote a row at t = 1.35e-15 s (below 1 ps) and ended early."""
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["creep", "--stress", "1e12"], "--stress = 1e+12",
             "[1e-12, 1.35e+07] Pa", "largest shear rate 1e+09 1/s")
    assert os.listdir(tmp_path) == []


# ---------------------------------------------------------------- a fresh user's findings (2)
def test_creep_stress_past_the_liquid_limit_names_the_option_as_typed(tmp_path, monkeypatch,
                                                                      capsys):
    """Before: 'imposed stress = 1e+08 ...' (the Step's name, not the option)."""
    monkeypatch.chdir(tmp_path)
    err = _refused(capsys, ["creep", "--stress", "1e8"], "--stress = 1e+08 is outside the valid "
                   "range [1e-12, 1.35e+07] Pa (the liquid alone takes an imposed stress at once")
    assert "imposed stress =" not in err
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("value", ["1e-300", "1e-13"])
def test_creep_stress_below_the_physical_stress_is_refused(value, tmp_path, monkeypatch, capsys):
    """Before: --stress 1e-300 ran (exit 0); STRESS_MIN is 1e-12 Pa."""
    monkeypatch.chdir(tmp_path)
    _refused(capsys, ["creep", "--stress", value], f"--stress = {value}",
             "[1e-12, 1e+12] Pa", "the stress water carries at the slowest rate")
    assert os.listdir(tmp_path) == []


def test_a_program_stress_past_the_liquid_limit_names_its_line_and_text(tmp_path, monkeypatch,
                                                                        capsys):
    """Before: 'imposed stress = 1e+08 ...' without the program line."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.txt").write_text("rest for 1 s\nstress 1e8 Pa for 1 s\n")
    _refused(capsys, ["program", "p.txt"], "program line 2: imposed stress of 'stress 1e8 Pa "
             "for 1 s' = 1e+08 is outside the valid range [1e-12, 1.35e+07] Pa, or 0",
             "the liquid alone takes an imposed stress at once")
    assert sorted(os.listdir(tmp_path)) == ["p.txt"]
    with pytest.raises(ValueError, match=r"program line 1: imposed stress of 'stress 1e-300 Pa "
                                         r"for 1 s' = 1e-300 is outside the valid range "
                                         r"\[1e-12, 1e\+12\] Pa, or 0"):
        parse_program("stress 1e-300 Pa for 1 s")


@pytest.mark.parametrize("angle, why", [("89", "the cone-plate conversions take the angle small"),
                                        ("-1", "the gap at the rim")])
def test_cone_angle_refusal_shows_its_real_range_and_reason(angle, why, tmp_path, monkeypatch,
                                                            capsys):
    """Before: --cone-angle 89 showed the range (-inf, 10] deg."""
    monkeypatch.chdir(tmp_path)
    err = _refused(capsys, ["flow-curve", "--geometry", "cone-plate", "--cone-angle", angle],
                   f"--cone-angle = {angle} is outside the valid range (0.00229183, 10] deg", why)
    assert "-inf" not in err


@pytest.mark.parametrize("argv, line", [
    (["flow-curve", "--phi_j=0.3"], "--phi_j=0.3: phi_j is a parameter of the material; give "
                                    "--set phi_j=0.3"),
    (["creep", "--phi-j", "0.3"], "--phi-j: phi_j is a parameter of the material; give --set "
                                  "phi_j=0.3"),
    (["flow-curve", "--bogus", "1"], "rheometer flow-curve: error: unrecognized arguments: "
                                     "--bogus 1")])
def test_a_material_parameter_given_as_an_option_is_pointed_to_set(argv, line, tmp_path,
                                                                   monkeypatch, capsys):
    """Before: 'rheometer: error: unrecognized arguments: --phi_j=0.3 (see rheometer --help)'."""
    monkeypatch.chdir(tmp_path)
    err = _refused(capsys, argv, line, f"(see rheometer {argv[0]} --help)")
    assert os.listdir(tmp_path) == []
    assert err.startswith(f"rheometer {argv[0]}: error:")


@pytest.mark.parametrize("kind, dims, words", [
    ("couette", dict(cup_radius=20.0), "cup radius = 20 is outside the valid range [0.013331, 10] m"),
    ("parallel-plate", dict(radius=1e-7), "radius = 1e-07 is outside the valid range [1e-06, 10] m"),
    ("parallel-plate", dict(gap=11.0), "gap = 11 is outside the valid range [1e-06, 10] m"),
    ("couette", dict(bob_length=1e-300), "bob length = 1e-300 is outside the valid range "
                                         "[1e-06, 10] m (the narrowest micro-gap rheometers)")])
def test_geometry_lengths_are_every_tiers_lengths(kind, dims, words):
    """Before: Geometry took any positive length (a 20 m cup from Python); now runkit.limits'
    LENGTH_MIN..LENGTH_MAX, the lengths of every tier, checked once by Geometry.make."""
    from rheometer.geometry import Geometry
    with pytest.raises(ValueError) as exc:
        Geometry.make(kind, **dims)
    assert words in str(exc.value)


def test_not_periodic_points_say_why_in_their_own_column(tmp_path, monkeypatch, capsys):
    """Before: the warning printed only the change d (the test also needs d r/(1-r) < tol); a
    note in ``reason`` would count the point failed. Now both in column not_periodic_why, and
    ``reason`` stays empty for every point that ran."""
    import pandas as pd
    monkeypatch.chdir(tmp_path)
    assert main(["oscillation", "--strain-amplitude", "0.01", "--cycles", "3", "--tol", "1e-10",
                 "--plot", "none"]) == 0
    out = capsys.readouterr().out
    assert "WARNING: not periodic within --cycles 3" in out
    assert "change d = " in out and "projected change d r/(1-r) = " in out
    pts = pd.read_csv("oscillation.csv", keep_default_na=False)
    assert {"reason", "not_periodic_why", "cycle_change", "converged"} <= set(pts.columns)
    assert (pts["reason"] == "").all()
    assert pts["not_periodic_why"].iloc[0].startswith("change d = ")
    assert "both must be < tol = 1e-10" in pts["not_periodic_why"].iloc[0]
