"""The shear1d command line end to end on tiny grids, and its handling of bad input: every
numeric option of every subcommand refuses NaN, inf, out-of-range and non-numbers with one line,
exit 2 and nothing written; physical ranges that depend on the material are refused at setup the
same way; sizes are bounded and the memory a run needs is checked before it starts."""

import argparse
import json
import math
import subprocess
import sys

import pandas as pd
import pytest

from runkit.params import Number
from shear1d.cli import _parser, main


def test_annular_command_writes_csv_json_png(tmp_path):
    out = tmp_path / "run"
    assert main(["annular", "--u-inner", "0.084", "--cells", "20", "--outputs", "62",
                 "--mode", "locked", "--quiet", "--out", str(out)]) == 0
    tag = "u84mm_s_locked"
    for name in (f"{tag}_velocity_profiles.csv", f"{tag}_cell_profiles.csv", f"{tag}_front.csv",
                 f"{tag}_fields.csv", f"{tag}_summary.json", f"{tag}_fields.png",
                 "velocity_profiles.png", "front_position.png"):
        assert (out / name).stat().st_size > 0, name
    prof = pd.read_csv(out / f"{tag}_velocity_profiles.csv")
    assert {"rotation_rad", "r_m", "v_over_u_inner", "v_over_omega_r"} <= set(prof.columns)
    assert sorted(prof["rotation_rad"].round(3).unique()) == [0.0, 0.1, 0.2, 0.31]
    s = json.loads((out / f"{tag}_summary.json").read_text())
    assert s["front_speed_m_per_s"] > 0 and s["front_fit_r2"] > 0.9
    assert not list(out.glob("*checkpoint*")) and not list(out.glob(".*"))


def test_slow_case_summary_is_strict_json_with_null_front(tmp_path):
    out = tmp_path / "slow"
    assert main(["annular", "--u-inner", "0.00084", "--cells", "12", "--outputs", "31",
                 "--mode", "locked", "--method", "explicit", "--quiet", "--out", str(out)]) == 0
    text = (out / "u0.84mm_s_locked_summary.json").read_text()
    assert "NaN" not in text and "Infinity" not in text
    s = json.loads(text)
    assert s["front_speed_m_per_s"] is None and s["band_rigidity_mean"] is None
    assert s["f_max"] < 0.05 * s["f_jam"]
    front = pd.read_csv(out / "u0.84mm_s_locked_front.csv")
    assert front["front_m"].isna().all() and front["bob_shear_stress_Pa"].notna().all()


def test_couette_command(tmp_path):
    assert main(["couette", "--speed", "0.01", "--cells", "10", "--time", "0.2", "--outputs", "10",
                 "--quiet", "--out", str(tmp_path)]) == 0
    wall = pd.read_csv(tmp_path / "couette_wall.csv")
    assert wall["wall_shear_stress_Pa"].iloc[-1] > 0
    assert (tmp_path / "couette.png").stat().st_size > 0


def _numeric_options():
    """(subcommand, option, Number) for every numeric option of every subcommand (--set, the
    material's parameters, has its own checks: test_set_overrides_the_material)."""
    sub = next(a for a in _parser()._actions if isinstance(a, argparse._SubParsersAction))
    for cmd, p in sub.choices.items():
        for act in p._actions:
            if act.option_strings and act.type is not None and act.dest != "set":
                assert isinstance(act.type, Number), (cmd, act.option_strings)
                yield cmd, act.option_strings[0], act.type


OPTIONS = list(_numeric_options())
BASE = {"annular": ["annular", "--u-inner", "0.084", "--cells", "8"],
        "couette": ["couette", "--speed", "0.01", "--cells", "8"]}


def _bad_values(num: Number):
    yield "nan"
    yield "inf"
    yield "-inf"
    yield "abc"
    if num.lo is not None:
        yield repr(num.lo - 1.0 - abs(num.lo)) if num.lo_closed else repr(num.lo)
    if num.hi is not None:
        yield repr(num.hi * 10 + 1) if num.hi_closed else repr(num.hi)
    if num.integer:
        yield "3.5"


CASES = [(cmd, opt, v) for cmd, opt, num in OPTIONS for v in _bad_values(num)]


@pytest.mark.parametrize("cmd, opt, value", CASES, ids=[f"{c}{o}={v}" for c, o, v in CASES])
def test_every_numeric_option_refuses_bad_values_with_one_line(tmp_path, capsys, cmd, opt, value):
    out = tmp_path / "out"
    args = [a for a in BASE[cmd]]
    if opt in args:                                  # replace the base value
        i = args.index(opt)
        del args[i:i + 2]
    if opt in ("--speed", "--stress"):
        args = ["couette"] + args[3:]
    with pytest.raises(SystemExit) as exc:
        main(args + [f"{opt}={value}", "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and opt in err[0] and "Traceback" not in err[0], err
    assert not out.exists()
    if opt in ("--speed", "--stress", "--u-inner"):   # the run's material's bounds, stated
        assert "inf)" not in err[0].split("valid range")[-1], err[0]
        low = "[1e-12, " if opt == "--stress" else "[1e-18, "     # the physical lower bounds
        assert low + ("0.1 G] Pa" if opt == "--stress" else "0.1 sqrt(G/rho)] m/s") in err[0] \
            or "outside the valid range " + low in err[0], err[0]


def test_the_options_have_physical_ranges():
    """The parser reads the numbers and states the range the library checks (shear1d.geometry,
    .model, .integrate, .scenes), each bound with its reason."""
    from shear1d.geometry import CELLS, LENGTH
    from shear1d.integrate import CHECKPOINT_EVERY, OUTPUTS, RTOL
    from shear1d.scenes import ROTATION

    ranges = {(c, o): n for c, o, n in OPTIONS}
    u = ranges[("annular", "--u-inner")]      # 0.1 sqrt(G/rho) of the run's material: later
    assert u.hi is None and "0.1 sqrt(G/rho)" in u.shown_range
    assert CELLS.hi.value == 20000 and ranges[("annular", "--cells")].range_text == "[4, 20000]"
    assert ranges[("annular", "--outputs")].integer and ranges[("couette", "--cells")].integer
    assert OUTPUTS.kind == "integer" and CHECKPOINT_EVERY.lo.value == 1e-12   # TIME_MIN
    assert ranges[("annular", "--r-inner")].range_text == "[1e-06, 10] m"
    assert ranges[("couette", "--gap")].range_text == "[1e-06, 10] m"
    for p in (CELLS, LENGTH, OUTPUTS, CHECKPOINT_EVERY, RTOL, ROTATION):
        assert all(b is None or b.why for b in (p.lo, p.hi)), p


@pytest.mark.parametrize("args, word", [
    (["annular", "--u-inner", "1e6", "--cells", "20", "--mode", "locked"], "--u-inner"),
    (["annular", "--mode", "drained"], "--mode"),
    (["annular", "--method", "rk4"], "--method"),
    (["annular", "--cells", "2"], "--cells"),
    (["annular", "--cells", "100000000"], "--cells"),
    (["annular", "--r-inner", "0.04", "--r-outer", "0.03"],
     "--r-outer = 0.03 is outside the valid range (0.04, 10] m (the cup must lie beyond"),
    (["annular", "--r-outer", "20"], "--r-outer = 20 is outside the valid range (0.0125, 10] m "
                                     "(a 10 m bed"),
    (["annular", "--rtol", "1"], "--rtol = 1 is outside the valid range [1e-12, 0.01] (a looser"),
    (["annular", "--rotation", "1e9"], "--rotation = 1e+09 is outside the valid range [1e-09, 100] "
                                       "rad (16 turns"),
    (["couette", "--speed", "0.01", "--gap", "1e-9"],
     "--gap = 1e-09 is outside the valid range [1e-06, 10] m (the narrowest micro-gap"),
    (["annular", "--cells", "3"], "--cells = 3 is outside the valid range [4, 20000] (fewer"),
    (["annular", "--phi", "0.7"], "--phi = 0.7 is outside the valid range [1e-06, 0.535) (steady"),
    (["annular", "--outputs", "0"], "--outputs = 0 is outside the valid range [1, 100000] ("),
    (["annular", "--checkpoint-every", "0"], "--checkpoint-every = 0 is outside the valid range "
                                             "[1e-12, 1e+09] s (a checkpoint"),
    (["annular", "--u-inner", "0.084", "--method", "explicit", "--dt", "1"],
     "--dt = 1 s is outside the explicit stability range"),
    (["couette", "--speed", "0.01", "--stress", "2"], "not allowed"),
    # the user's option and its range in its units, not the model's wall_speed / wall_stress
    # (the lower ends: the physical SPEED_MIN and STRESS_MIN of runkit.limits, no longer 0)
    (["couette", "--speed", "2"], "--speed = 2 is outside the valid range [1e-18, 1.53156] m/s"),
    (["couette", "--speed=-0.01"], "--speed = -0.01 is outside the valid range [1e-18, 1.53156] "
                                   "m/s"),
    (["couette", "--speed", "-1e-2"], "--speed = -0.01 is outside the valid range [1e-18, "
                                      "1.53156]"),
    (["couette", "--stress", "1e5"], "--stress = 100000 is outside the valid range [1e-12, 38000] "
                                     "Pa"),
    (["couette", "--stress", "0"], "--stress = 0 is outside the valid range [1e-12, 38000] Pa"),
    (["couette", "--speed", "0.01", "--phi", "0.6"], "--phi"),  # above phi_j
    (["annular", "--mass-fraction", "0.6"], "--mass-fraction"),   # phi above phi_j by Eq. 20
    (["annular", "--phi", "0.5", "--mass-fraction", "0.5"], "not both"),
    (["couette", "--speed", "0.01", "--material", "singh2018_a"], "normalised"),
    (["annular", "--material", "nosuch.json"], "nosuch.json"),
    (["couette", "--speed", "0.01", "--mode", "both"], "--mode"),
    (["annular", "--u-inner", "0.084", "0.084"], "once"),
    (["annular", "--u-inner", "0.00084", "--rotation", "100", "--cells", "20000", "--r-outer",
      "0.2", "--method", "explicit", "--outputs", "10"], "cell-steps"),
])
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, args, word):
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "shear1d", *args, "--out", str(out)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr and word in lines[0], lines[0]
    assert not out.exists()


def test_a_run_too_large_for_memory_is_refused_with_its_estimate(tmp_path, capsys, monkeypatch):
    import runkit.limits as checks

    monkeypatch.setattr(checks, "available_memory", lambda: 2e9)
    out = tmp_path / "big"
    assert main(["annular", "--cells", "20000", "--r-outer", "0.2", "--outputs", "1000", "--out",
                 str(out)]) == 2
    err = capsys.readouterr().err
    assert "GB (estimate)" in err and "--cells" in err and not out.exists()


def test_memory_estimate_covers_the_measured_peak():
    """The estimate (48 floats per cell and output) against the arrays a run really holds."""
    from shear1d.integrate import FLOATS_PER_CELL_OUTPUT, memory_estimate, solve
    from shear1d.scenes import annular_shear_jamming, fields_frame, front_frame, profile_frames

    pb, t_end = annular_shear_jamming(0.084, n_cells=40, rotation=0.02)
    res = solve(pb, t_end, n_out=20, method="explicit")
    held = res.y.nbytes + res.diag.nbytes
    held += sum(res.field(k).nbytes for k in ("v", "f", "phi", "sigma_rth", "pressure",
                                              "shear_stress", "shear_rate",
                                              "plastic_shear_rate"))
    held += sum(int(f.memory_usage(deep=True).sum()) for f in (
        *profile_frames(res), front_frame(res), fields_frame(res)))
    floats = held / 8 / (40 * 21)
    assert floats < FLOATS_PER_CELL_OUTPUT, floats
    assert memory_estimate(100_000_000, 310) > 1e12
    assert math.isclose(memory_estimate(10, 9, runs=2) - 50e6, 2 * 48 * 8 * 10 * 10)


def test_material_file_and_mass_fraction(tmp_path):
    """A user's material file runs on Table 4's moduli; a mass fraction sets phi by Eq. (20)."""
    import json

    import rheology
    from rheology.sample import Densities, volume_fraction

    fit = tmp_path / "material.json"
    rheology.materials.save_material(fit, rheology.get_material("hermes2016", eta0=0.01))
    out = tmp_path / "o"
    w = 0.45
    proc = subprocess.run([sys.executable, "-m", "shear1d", "annular", "--material", str(fit),
                           "--mass-fraction", str(w), "--u-inner", "0.084", "--mode", "locked",
                           "--cells", "20", "--rotation", "0.02", "--outputs", "5", "--quiet",
                           "--out", str(out)], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    phi = float(volume_fraction(w, Densities(liquid=1620.0)))     # Table 4 is density matched
    summary = json.loads((out / "u84mm_s_locked_summary.json").read_text())
    assert summary["phi0"] == pytest.approx(phi, rel=1e-12)
    assert f"phi = {phi:.5g}" in proc.stdout


def test_drive_range_follows_the_material_and_names_the_option():
    """--speed / --u-inner up to 0.1 c_s and --stress up to 0.1 G of the run's material and
    phi, refused by the option's name in its units (a stiffer skeleton allows faster walls)."""
    import rheology
    from shear1d.model import max_wall_speed
    from shear1d.scenes import plane_couette

    stiff = rheology.get_material("rod_impact")               # G = 3.8e7 Pa: 100 x annular
    top = max_wall_speed(stiff, 0.5)
    assert 15 < top < 18                                      # 0.1 sqrt(G/rho)
    plane_couette(5.0, material=stiff, phi0=0.5, n_cells=8)   # above annular's 1.53 m/s: fine
    with pytest.raises(ValueError, match=rf"wall_speed = 20 is outside the valid range "
                                         rf"\[1e-18, {top:g}\] m/s \(0.1 c_s"):
        plane_couette(20.0, material=stiff, phi0=0.5, n_cells=8)
    with pytest.raises(ValueError, match=r"wall_stress = 4e\+06 is outside the valid range "
                                         r"\[1e-12, 3\.8e\+06\] Pa \(0.1 G"):
        plane_couette(stress=4e6, material=stiff, phi0=0.5, n_cells=8)
    assert main(["couette", "--speed", "20", "--material", "rod_impact", "--phi", "0.5"]) == 2


def test_a_stiffer_material_allows_a_faster_bob(tmp_path, capsys):
    """--u-inner is bounded by the run's material, not annular_shear's: 5 m/s is refused for
    annular_shear (0.1 c_s = 1.53 m/s) and passes the checks for rod_impact (16 m/s); the
    refusal is the one line of the Couette problem's check."""
    from shear1d.cli import main

    args = ["annular", "--u-inner", "5", "--cells", "8", "--out", str(tmp_path / "a")]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--u-inner = 5 is outside the valid range [1e-18, 1.5" in err[0], err
    assert not (tmp_path / "a").exists()
    stiff = ["--material", "rod_impact", "--phi", "0.5", "--r-outer", "0.0401", "--rotation",
             "0.1"]
    # refused at --cells 0 (the grid is checked first), not at --u-inner 5
    assert main(args + stiff + ["--cells", "0"]) == 2
    err = capsys.readouterr().err
    assert "--u-inner" not in err and "--cells" in err, err


def test_two_phase_without_a_grain_size_names_the_physical_range(tmp_path, capsys):
    """d = 0 (no grain size) with the two-phase mode said "valid range (0, inf)": the range is
    the grain size's physical one."""
    from shear1d.cli import main

    out = tmp_path / "o"
    assert main(["annular", "--set", "d=0", "--cells", "8", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "d = 0 is outside the valid range [1e-08, 0.01] m" in err[0], err
    assert "Darcy drag" in err[0] and not out.exists()


def test_default_cup_radius_is_named_as_the_default(tmp_path, capsys):
    """--r-inner beyond the default cup: the refusal says the --r-outer it names is the default
    (the user did not type it)."""
    from shear1d.cli import main

    rc = main(["annular", "--r-inner", "0.05", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "--r-outer = 0.036 (the default)" in err[0], err
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------ fresh-user faults 9, 10, 11
@pytest.mark.parametrize("args, word", [
    # fault 9: an empty --out wrote every file into the current folder
    (["annular", "--u-inner", "0.084", "--cells", "20", "--quiet", "--out", ""],
     "--out = '' is empty"),
    (["couette", "--speed", "0.01", "--cells", "4", "--quiet", "--out", ""],
     "--out = '' is empty"),
    (["couette", "--speed", "0.01", "--cells", "4", "--quiet", "--out", "  "],
     "is empty: give the output folder's name"),
    # fault 10: --time had no upper bound (1e300 ran minutes, then IDA failed)
    (["couette", "--speed", "0.01", "--time", "1e300", "--quiet", "--cells", "4"],
     "--time = 1e+300 is outside the valid range [1e-12, 1e+09] s (30 years"),
    # --time had no lower bound (1e-300 ran and wrote its files): the shared durations
    (["couette", "--speed", "0.01", "--time", "1e-300", "--quiet", "--cells", "4"],
     "--time = 1e-300 is outside the valid range [1e-12, 1e+09] s"),
    # fault 11: --ramp-time had no upper bound; now at most the rotation time at full speed
    (["annular", "--u-inner", "0.084", "--cells", "20", "--ramp-time", "1e9"],
     "--ramp-time = 1e+09 s is outside the valid range [1e-12, 0.04613] s, or 0"),
    (["annular", "--u-inner", "0.00084", "0.084", "--cells", "20", "--ramp-time", "0.05"],
     "--ramp-time = 0.05 s is outside the valid range [1e-12, 0.04613] s, or 0"),
    (["annular", "--u-inner", "0.084", "--cells", "20", "--ramp-time", "1e10"],
     "--ramp-time = 1e+10 is outside the valid range [1e-12, 1e+09] s, or 0 (30 years"),
])
def test_fresh_user_refusals_exit_2_one_line_nothing_written(args, word, tmp_path, monkeypatch,
                                                              capsys):
    monkeypatch.chdir(tmp_path)
    try:
        code = main(args)                  # refused at setup: main returns the status
    except SystemExit as exc:              # refused by the parser
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0] and "Traceback" not in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_ramp_time_bound_is_the_rotation_time_of_the_fastest_speed():
    from shear1d.scenes import check_ramp as _check_ramp

    top = 0.31 * 0.0125 / 0.084
    _check_ramp(top, 0.31, 0.0125, [0.00084, 0.084])        # at the bound: accepted
    _check_ramp(0.0, 0.31, 0.0125, [0.084])
    with pytest.raises(ValueError, match=r"ramp_time = 0\.0462 s .*\[1e-12, 0\.04613\] s, or 0"):
        _check_ramp(0.0462, 0.31, 0.0125, [0.00084, 0.084])


def test_sundials_error_lines_stay_off_stdout(tmp_path, monkeypatch, capsys):
    """Fault 10: sksundae prints SUNDIALS' errors on stdout ('[IDASolve, Error: -22] ...'). They
    are kept off it and the failure's one line (exit 1) carries their words."""
    import runkit.ida

    real = runkit.ida.IDA

    def few_steps(*a, **kw):                      # IDA gives up after 3 steps: a real failure
        kw["max_num_steps"] = 3
        return real(*a, **kw)
    monkeypatch.setattr(runkit.ida, "IDA", few_steps)
    rc = main(["couette", "--speed", "0.01", "--cells", "4", "--time", "0.2", "--outputs", "2",
               "--quiet", "--out", str(tmp_path / "o")])
    cap = capsys.readouterr()
    assert rc == 1
    assert "Error: -22" not in cap.out and "IDASolve" not in cap.out, cap.out
    err = cap.err.strip().splitlines()
    assert len(err) == 1 and "IDA failed at t = " in err[0], err
    assert "[SUNDIALS: IDASolve, Error: -22] At t = " in err[0] and "mxstep" in err[0], err


@pytest.mark.parametrize("args, words", [
    # the explicit cell-step count cells x t_end / dt: every option that sets it is named
    (["couette", "--speed", "0.01", "--time", "1e5", "--cells", "4", "--method", "explicit",
      "--dt", "1e-9"], ["--cells 4", "(--time)", "--dt = 1e-09 s", "--dt >= 4e-07 s",
                        "t_end <= 250 s"]),
    (["couette", "--speed", "0.01", "--time", "1e9", "--cells", "4", "--method", "explicit"],
     ["--cells 4", "(--time)", "(the default, half the stability limit)", "--method ida"]),
    (["annular", "--u-inner", "0.00084", "--rotation", "100", "--cells", "20000", "--r-outer",
      "0.2", "--method", "explicit", "--outputs", "10"],
     ["--cells 20000", "--rotation x --r-inner / --u-inner", "fewer --cells"]),
])
def test_explicit_cell_step_limit_names_every_option_that_sets_it(args, words, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(args + ["--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cell-steps" in err[0], err
    for w in words:
        assert w in err[0], (w, err[0])
    if "--time" in args and "1e9" in args:
        assert "--dt >=" not in err[0]        # no step within the stability limit fits
    assert not out.exists()


# ---------------------------------------------------------------- lengths against the grain size
@pytest.mark.parametrize("args, words", [
    # before: f = nan in the first Table 8 update, exit 1, an empty folder left
    (["couette", "--speed", "0.01", "--gap", "1e-5"],
     ["--gap = 1e-05 m is outside the valid range [0.000585, 10] m (at 100 cells each cell",
      "d = 5.85e-06 m"]),
    (["couette", "--speed", "0.01", "--gap", "1e-4"],
     ["--gap = 0.0001 m", "at most 17 cells at this gap"]),
    # before: t_end = 4e-298 s and a failed first update
    (["annular", "--r-inner", "1e-300", "--r-outer", "0.01"],
     ["--r-inner = 1e-300 is outside the valid range [1e-06, 10] m (the narrowest"]),
    (["annular", "--r-inner", "2e-5", "--r-outer", "0.01"],
     ["--r-inner = 2e-05 m is outside the valid range [5.85e-05, 10] m (the bob must be a "
      "continuum wall"]),
    (["annular", "--cells", "8000"],
     ["--r-outer = 0.036 m (the default) is outside the valid range [0.0593, 10] m (at a bob "
      "radius of 0.0125 m and 8000 cells", "at most 4017 cells"]),
])
def test_lengths_below_the_grain_size_are_refused_up_front(args, words, tmp_path, capsys):
    out = tmp_path / "o"
    assert main(args + ["--quiet", "--out", str(out)]) == 2
    cap = capsys.readouterr()
    err = cap.err.strip().splitlines()
    assert len(err) == 1 and cap.out == "", cap
    for w in words:
        assert w in err[0], (w, err[0])
    assert not out.exists()


def test_smallest_gap_runs_the_newtonian_startup(tmp_path):
    """At the smallest gap (one grain per cell, 4 cells) the run is well-posed: at phi0 = 0.2
    (no jamming) the momentum diffusion time H^2 rho/eta ~ 3e-8 s << 1e-3 s, so the wall stress
    is the steady mixture stress at the rate U/H (rheology's steady solver)."""
    import pandas as pd

    import rheology
    from rheology.materials import scene_material
    from shear1d.geometry import min_gap
    gap = min_gap(4, 5.85e-6)
    steady = rheology.steady_states_rate(1e-4 / gap, 0.2, scene_material("annular_shear",
                                                                          "annular_shear"))
    out = tmp_path / "o"
    assert main(["couette", "--speed", "1e-4", "--gap", repr(gap), "--cells", "4", "--phi", "0.2",
                 "--time", "1e-3", "--outputs", "4", "--quiet", "--out", str(out)]) == 0
    wall = pd.read_csv(out / "couette_wall.csv")
    assert wall["wall_shear_stress_Pa"].iloc[-1] == pytest.approx(float(steady.shear_stress[0]),
                                                                  rel=1e-3)


def test_a_run_failing_at_start_leaves_no_folder(tmp_path, monkeypatch, capsys):
    import shear1d.scenes as scenes

    def fail(*a, **k):
        raise RuntimeError("solver failed at t = 0")
    monkeypatch.setattr(scenes, "integrate", fail)
    for args in (["couette", "--speed", "0.01", "--cells", "8"],
                 ["annular", "--u-inner", "0.084", "--mode", "locked", "--cells", "8"]):
        out = tmp_path / args[0]
        assert main(args + ["--quiet", "--out", str(out)]) == 1
        assert "solver failed" in capsys.readouterr().err
        assert not out.exists()
    kept = tmp_path / "kept"                  # a folder the user had is never removed
    kept.mkdir()
    assert main(["couette", "--speed", "0.01", "--cells", "8", "--quiet", "--out", str(kept)]) == 1
    assert kept.is_dir()


@pytest.mark.parametrize("args, name", [
    (["couette", "--speed", "0.01", "--cells", "8"], "couette.checkpoint.npz"),
    (["annular", "--u-inner", "0.084", "--mode", "locked", "--cells", "8"],
     "u84mm_s_locked.checkpoint.npz"),
])
def test_resume_from_a_corrupt_checkpoint_prints_only_the_refusal(args, name, tmp_path, capsys):
    """Before: annular printed 'resuming from ...' on stdout, then the refusal."""
    out = tmp_path / "o"
    out.mkdir()
    (out / name).write_text("garbage")
    assert main(args + ["--quiet", "--resume", "--out", str(out)]) == 2
    cap = capsys.readouterr()
    assert cap.out == "", cap.out
    err = cap.err.strip().splitlines()
    assert len(err) == 1 and f"{name} is corrupt" in err[0], err
    assert sorted(p.name for p in out.iterdir()) == [name]


def test_csv_writes_no_negative_zero(tmp_path):
    """runkit.io.atomic_write_csv writes -0.0 as 0.0 in every float column (shear1d couette
    --speed 1e-300 wrote f_mean = -0.0), NaN still empty where allowed, the frame unchanged."""
    import numpy as np

    from runkit.io import atomic_write_csv

    df = pd.DataFrame({"a": [-0.0, 1.5, -2.0], "b": np.array([-0.0, 0.0, np.nan], np.float32),
                       "n": [0, -1, 2], "s": ["-0.0", "x", "y"]})
    atomic_write_csv(tmp_path / "z.csv", df, empty_ok=("b",))
    text = (tmp_path / "z.csv").read_text()
    assert text.splitlines() == ["a,b,n,s", "0.0,0.0,0,-0.0", "1.5,0.0,-1,x", "-2.0,,2,y"], text
    assert math.copysign(1.0, df["a"][0]) == -1.0       # the caller's frame is not changed
    out = tmp_path / "sp"                 # 1e-300 is refused now: the slowest physical speed
    assert main(["couette", "--speed", "1e-18", "--cells", "8", "--time", "0.01", "--outputs",
                 "4", "--quiet", "--out", str(out)]) == 0
    for f in out.glob("*.csv"):
        x = pd.read_csv(f).select_dtypes("number").to_numpy(float)
        assert not np.any((x == 0) & np.signbit(x)), f.name
    wall = pd.read_csv(out / "couette_wall.csv")  # 1e-300 gave f_mean = -3.3e-321
    assert (wall["f_mean"] >= 0).all() and (wall["mean_shear_rate_per_s"].iloc[-1]
                                            == pytest.approx(1e-16, rel=1e-6))


@pytest.mark.parametrize("item, message", [
    ("rules=mpm3d", "--set rules = 'mpm3d' is not one of table8, mpm_3d"),
    ("K0=-1", "K0 = -1 is outside the valid range [0, inf) (material annular_shear; K0 >= 0: "
              "the structure f relaxes toward its steady value"),
    ("name=x", "--set name: name is a text field of the material"),
    ("G=abc", "--set G = 'abc' is not a number"),
])
def test_set_overrides_the_material(tmp_path, capsys, item, message):
    """--set NAME=VALUE sets a parameter of the run's material (rules among them); a bad one is
    refused in one line, exit 2, nothing written."""
    out = tmp_path / "out"
    try:                              # refused by the parser (SystemExit) or by the material
        code = main(["couette", "--speed", "0.01", "--cells", "8", "--set", item, "--out",
                     str(out)])
    except SystemExit as exc:
        code = exc.code
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not out.exists()
    assert main(["couette", "--speed", "0.01", "--set", "rules=mpm_3d", "--method", "dae",
                 "--out", str(out)]) == 2
    assert "method 'dae' is the smooth form of the table8 rules" in capsys.readouterr().err
    assert not out.exists()


def test_set_rules_reaches_the_law(tmp_path):
    """The same run under the two rules: the kernel parameters (and so the checkpoint's
    signature) carry the rules' code."""
    from shear1d.cli import _parser as parser, _sample

    for rules, code in (("table8", 0.0), ("mpm_3d", 1.0)):
        args = parser().parse_args(["couette", "--speed", "0.01", "--set", f"rules={rules}",
                                    "--out", str(tmp_path)])
        m, _ = _sample(args)
        assert m.rules == rules and m.kernel_array()[-1] == code


# ------------------------------------------- every dimensional option at the physical limits
#: the numeric options with a unit, and the physical lower bound (runkit.limits) each is held
#: to (None: a bound derived from another option, the cup beyond the bob)
def _lower_bounds():
    from runkit import limits as L
    from shear1d.integrate import CHECKPOINT_EVERY
    from shear1d.scenes import ROTATION

    return {"--u-inner": L.SPEED_MIN, "--speed": L.SPEED_MIN, "--stress": L.STRESS_MIN,
            "--r-inner": L.LENGTH_MIN, "--r-outer": None, "--gap": L.LENGTH_MIN,
            "--time": L.TIME_MIN, "--ramp-time": L.TIME_MIN, "--dt": L.TIME_MIN,
            "--checkpoint-every": CHECKPOINT_EVERY.lo, "--rotation": ROTATION.lo,
            "--phi": L.PHI_MIN, "--grain-density": L.DENSITY_MIN,
            "--liquid-density": L.DENSITY_MIN, "--water-density": L.DENSITY_MIN}


LOWER = _lower_bounds()
#: the numeric options without a unit (counts, a tolerance, fractions of Eq. 20)
DIMENSIONLESS = {"--cells", "--outputs", "--rtol", "--mass-fraction", "--swelling",
                 "--pore-fraction"}
DIMENSIONAL = [(cmd, opt) for cmd, opt, _ in OPTIONS if opt not in DIMENSIONLESS]
EXTREMES = [(cmd, opt, v) for cmd, opt in DIMENSIONAL for v in ("1e-300", "1e300", "nan")]


def test_every_numeric_option_is_classified():
    """A new numeric option of any subcommand must be put in LOWER or DIMENSIONLESS."""
    assert {o for _, o, _ in OPTIONS} == set(LOWER) | DIMENSIONLESS
    assert {c for c, _ in DIMENSIONAL} == {"annular", "couette"}


@pytest.mark.parametrize("cmd, opt, value", EXTREMES, ids=[f"{c}{o}={v}" for c, o, v in EXTREMES])
def test_every_dimensional_option_at_the_extremes(cmd, opt, value, tmp_path, monkeypatch, capsys):
    """1e-300, 1e300 and nan for every option with a unit: exit 2, one line naming it with its
    valid range (no 0 or inf where the physics has a limit) and the reason, nothing written.
    Before: --speed/--stress 1e-300 ran (couette_wall.csv with f_mean = -3.3e-321),
    --u-inner 1e-300 stated subnormal rotation bounds, --dt 1e-300 a t_end <= 5e-291 s, and nan
    a range (0, inf)."""
    monkeypatch.chdir(tmp_path)
    base = {"annular": ["annular", "--u-inner", "0.084", "--rotation", "0.01"],
            "couette": ["couette", "--speed", "0.01", "--time", "0.01"]}[cmd]
    if opt in ("--speed", "--stress"):
        base = base[:1] + base[3:]
    elif opt in base:
        del base[base.index(opt):base.index(opt) + 2]
    argv = base + ["--cells", "8", "--outputs", "2", "--quiet", "--out", "o", opt, value]
    try:
        code = main(argv)                 # refused at setup: main returns the status
    except SystemExit as exc:             # refused by the parser
        code = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2, (argv, err)
    assert len(err) == 1 and "Traceback" not in err[0], err
    line = err[0]
    assert f"{opt} = " in line and "valid range " in line, line
    rng = line.split("valid range ")[1]
    assert "inf" not in rng.split(" (")[0], line             # a real range, not (0, inf)
    low = LOWER[opt]
    if value == "nan":
        assert "must be finite" in line, line
    else:
        assert rng.rstrip().endswith(")") and " (" in rng, line   # the reason stated
        if value == "1e-300" and low is not None:
            assert rng.startswith(f"[{low.value:g}, ") and low.why in line, line
    if low is not None:
        assert rng.startswith(f"[{low.value:g}, "), line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("cmd, words", [
    # annular runs both modes by default: its refusal of an unknown --mode lists "both" too
    ("annular", "--mode = 'xx' is not one of locked, two-phase, both"),
    ("couette", "--mode = 'xx' is not one of locked, two-phase"),
])
def test_an_unknown_mode_is_refused_with_the_command_s_choices(tmp_path, capsys, cmd, words):
    out = tmp_path / "out"
    args = ["annular", "--u-inner", "0.084"] if cmd == "annular" else ["couette", "--speed",
                                                                       "0.01"]
    assert main(args + ["--mode", "xx", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not out.exists()
