"""The ``rheometer`` command line end to end: CSV columns and numbers, figures, bad input."""

import os
import re
import shutil
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

import rheology
from rheometer.cli import main

HERMES = rheology.get_material("hermes2016")


def _script():
    exe = shutil.which("rheometer", path=os.path.dirname(sys.executable))
    return [exe] if exe else [sys.executable, "-m", "rheometer.cli"]


def test_flow_curve_default_writes_csv_and_png(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve"]) == 0
    assert "flow_curve.csv" in capsys.readouterr().out
    df = pd.read_csv(tmp_path / "flow_curve.csv")
    assert (tmp_path / "flow_curve.png").stat().st_size > 10_000
    assert sorted(df["phi"].unique()) == [0.48, 0.50, 0.52] and len(df) == 600


def test_flow_curve_issue_command_numbers(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve", "--material", "hermes2016", "--phi", "0.48", "0.50", "0.52",
                 "--stress-range", "1e-3", "1e4", "--points", "200", "--out", "fc.csv"]) == 0
    df = pd.read_csv("fc.csv")
    for col in ("phi", "shear_stress_Pa", "granular_shear_stress_Pa", "shear_rate_per_s",
                "viscosity_Pa_s", "f", "granular_pressure_Pa"):
        assert col in df.columns
    assert (tmp_path / "fc.png").exists()
    d = df[df["phi"] == 0.52]
    ref = rheology.steady_state_stress(np.logspace(-3, 4, 200), 0.52, HERMES)
    assert np.allclose(d["granular_shear_stress_Pa"], ref.taubar, rtol=1e-12)
    assert np.allclose(d["shear_rate_per_s"], ref.shear_rate, rtol=1e-12)
    assert np.allclose(d["shear_stress_Pa"], ref.taubar + HERMES.eta0 * (1 + 2.5 * 0.52)
                       * ref.shear_rate, rtol=1e-12)
    assert np.allclose(d["viscosity_Pa_s"], d["shear_stress_Pa"] / d["shear_rate_per_s"])


def test_flow_curve_rate_control_lists_branches(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve", "--phi", "0.52", "--control", "rate", "--rate-range", "0.05",
                 "0.12", "--points", "3", "--plot", "none"]) == 0
    df = pd.read_csv("flow_curve.csv")
    assert {"branch", "stable"} <= set(df.columns)
    at = df[np.isclose(df["shear_rate_per_s"], 0.12)]          # rising and falling branches
    assert list(at["branch"]) == [0, 1] and list(at["stable"]) == [True, False]
    assert not (tmp_path / "flow_curve.png").exists()


def test_flow_curve_rate_control_names_the_rates_without_a_steady_state(tmp_path, monkeypatch,
                                                                         capsys):
    """Rate control above the DST/jamming rate has no steady state (the rows are absent): the
    command says at how many rates and why, and every imposed rate is either a row or counted."""
    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve", "--phi", "0.48", "0.52", "--control", "rate", "--rate-range", "1",
                 "10", "--points", "5", "--plot", "none"]) == 0
    df = pd.read_csv("flow_curve.csv")
    out = capsys.readouterr().out
    for ph in (0.48, 0.52):
        rows = int(df.loc[np.isclose(df["phi"], ph), "index"].nunique())
        missing = 5 - rows
        assert missing > 0                                  # both jam within 1-10 1/s
        assert f"phi = {ph:g}: no steady state at {missing} of 5 rates" in out
        assert f"phi_c = {HERMES.phi_c:g}" in out
        # a rate without a row is above every rate with one (jamming at high rates only)
        if rows:
            assert df.loc[np.isclose(df["phi"], ph), "shear_rate_per_s"].max() < 10.0


def test_relax_issue_command(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["relax", "--material", "hermes2016", "--phi", "0.52", "--stress", "10", "--G",
                 "1e4", "--K0", "1", "--t-end", "50", "--out", "relax.csv"]) == 0
    df = pd.read_csv("relax.csv")
    for col in ("time_s", "shear_stress_Pa", "f", "plastic_shear_rate_per_s"):
        assert col in df.columns
    st = rheology.steady_state_stress(10.0, 0.52, HERMES)
    assert df["shear_stress_Pa"].iloc[0] == pytest.approx(10.0)
    assert df["f"].iloc[0] == pytest.approx(float(st.f), rel=1e-12)
    assert df["plastic_shear_rate_per_s"].iloc[0] == pytest.approx(float(st.shear_rate), rel=1e-9)
    assert df["time_s"].iloc[-1] == pytest.approx(50.0)
    # decays monotonically, to IDA's tolerance (rtol 1e-7 of the initial stress): once the stress
    # is ~1e-10 Pa the signed law's plastic rate may flip sign within that tolerance
    assert np.all(np.diff(df["shear_stress_Pa"]) <= 1e-7 * df["shear_stress_Pa"].iloc[0])
    assert (tmp_path / "relax.png").exists()


def test_startup_and_creep_end_on_steady_states(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["startup", "--phi", "0.45", "--rate", "1", "--t-end", "60", "--rtol", "1e-9"]) == 0
    df = pd.read_csv("startup.csv")
    ss = rheology.steady_state_stress(df["granular_shear_stress_Pa"].iloc[-1], 0.45, HERMES)
    assert float(ss.shear_rate) == pytest.approx(1.0, rel=1e-6)
    assert main(["creep", "--phi", "0.52", "--stress", "10", "--t-end", "600", "--rtol",
                 "1e-9"]) == 0
    df = pd.read_csv("creep.csv")
    ss = rheology.steady_states_mixture_stress(10.0, 0.52, HERMES)
    assert df["shear_rate_per_s"].iloc[-1] == pytest.approx(float(ss.shear_rate[0]), rel=1e-6)
    assert set(df.columns) >= {"time_s", "shear_rate_per_s", "shear_stress_Pa", "f"}


def test_program_and_material_point_and_materials(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    # 3 s: at phi 0.50 the sample shear-jams at 1 1/s and its elastic strain taubar/G passes the
    # small-strain limit 0.1 at t ~ 4.4 s (refused since; see test_elastic_strain_past_...)
    (tmp_path / "steps.txt").write_text("shear at 1 1/s for 3 s\nrest for 5 s\n")
    assert main(["program", "steps.txt", "--phi", "0.48", "0.50"]) == 0
    df = pd.read_csv("program.csv")
    assert set(df["phi"]) == {0.48, 0.50} and set(df["step"]) == {1, 2}
    assert main(["material-point", "--t-end", "1", "--dt", "1e-3"]) == 0
    mp = pd.read_csv("material_point.csv")
    assert {"shear_stress_Pa", "granular_pressure_Pa", "N1_Pa", "phi0"} <= set(mp.columns)
    assert main(["materials"]) == 0
    out = capsys.readouterr().out
    assert "hermes2016" in out and "Hermes et al." in out


@pytest.mark.parametrize("argv, match", [
    (["flow-curve", "--phi", "0.7"], "phi = 0.7 is outside the valid range"),
    (["flow-curve", "--material", "cornflour"], "unknown material 'cornflour'"),
    (["flow-curve", "--set", "eta0=-1"], "eta0 = -1 is outside"),
    (["flow-curve", "--set", "colour=3"], "unknown material parameter"),
    (["flow-curve", "--stress-range", "10", "1"], "--stress-range 10 1 must satisfy"),
    (["relax", "--G", "-5"], "--G = -5 is outside the valid range [1, 1e+12] Pa (the weakest"),
    (["startup", "--G", "1e300"], "--G = 1e300 is outside the valid range [1, 1e+12] Pa (five"),
    (["relax", "--phi", "nan"], "--phi = nan: must be finite"),
    (["startup", "--rate", "-1"], "--rate = -1 is outside"),
    (["flow-curve", "--set", "eta0=inf"], "--set eta0 = inf: must be finite"),
    (["flow-curve", "--plot", "fig.xyz"], "--plot = 'fig.xyz': format 'xyz' is not one of"),
    (["program", "--resume"], "--resume: no checkpoint at program.checkpoint.npz"),
    (["program", "missing.txt"], "program file 'missing.txt' not found"),
    (["material-point", "--dt", "5", "--t-end", "1"], "--dt = 5 is outside"),
    (["flow-curve", "--out", "table.txt"], "--out = 'table.txt': format 'txt' is not one of csv"),
])
def test_bad_input_gives_one_line_and_status_2(argv, match, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    try:
        status = main(argv)
    except SystemExit as exc:                  # argparse refuses an option's value
        status = exc.code
    assert status == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and match in err and "Traceback" not in err
    assert not any(tmp_path.iterdir()), list(tmp_path.iterdir())


@pytest.mark.parametrize("argv, label", [
    (["program", "d"], "program file 'd'"),
    (["fit", "d", "--phi", "0.45"], "data file 'd'"),
    (["fit-relaxation", "d", "--phi", "0.45", "--material", "hermes2016", "--stress0", "10"],
     "data file 'd'"),
    (["flow-curve", "--material", "./d"], "material file 'd'"),
])
def test_a_folder_given_for_a_file_is_named_as_one(argv, label, tmp_path, monkeypatch, capsys):
    """A folder where an input file is expected was reported as 'not found'."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "d").mkdir()
    try:
        status = main(argv)
    except SystemExit as exc:
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1, err
    assert f"{label} is a folder, not a file" in err, err
    assert [p.name for p in tmp_path.iterdir()] == ["d"] and not any((tmp_path / "d").iterdir())


def test_binary_program_file_is_named(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "garbage.bin").write_bytes(bytes(range(128, 256)) * 4)
    (tmp_path / "nul.txt").write_bytes(b"shear at 1 1/s for 1 s\x00\n")
    for name in ("garbage.bin", "nul.txt"):
        assert main(["program", name]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"program file {name!r} is not a text program" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["garbage.bin", "nul.txt"]


def test_console_script_bad_input_and_parse_error(tmp_path):
    (tmp_path / "bad.txt").write_text("shear at 1 1/s for 5 s\nwobble for 3 s\n")
    for argv, match in ((["relax", "--phi", "0.6"], "phi = 0.6"),
                        (["program", "bad.txt"], "program line 2: unknown step 'wobble'"),
                        (["flow-curve", "--phi"], "expected at least one argument")):
        r = subprocess.run(_script() + argv, cwd=tmp_path, capture_output=True, text=True,
                           timeout=120)
        assert r.returncode == 2, r.stderr
        assert r.stderr.count("\n") == 1 and match in r.stderr and "Traceback" not in r.stderr
        assert r.stdout == ""


def test_a_parameter_set_twice_is_refused(tmp_path, monkeypatch, capsys):
    """--set NAME=... twice is ambiguous: one line, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve", "--set", "eta0=1", "--set", "eta0=2"]) == 2
    assert "--set eta0 given twice" in capsys.readouterr().err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("cmd", [["flow-curve"], ["startup", "--t-end", "1"], ["materials",
                                 "--material", "hermes2016"], ["fit", "x.csv", "--phi", "0.4"]])
@pytest.mark.parametrize("key", ["name", "citation", "notes", "units"])
def test_text_fields_are_not_settable(cmd, key, tmp_path, monkeypatch, capsys):
    """--set on a material's text field (name crashed with a TypeError; citation, notes ran):
    one line naming the key and the settable (numeric) keys, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    try:
        status = main([*cmd, "--set", f"{key}=1"])
    except SystemExit as exc:
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"--set {key}: {key} is a text field" in err
    settable = err.split("settable: ")[1]
    assert "eta0" in settable and "phi_j" in settable
    assert not any(k in settable for k in ("name", "citation", "notes", "units"))
    assert not any(tmp_path.iterdir())


def test_unknown_and_unset_overrides_name_the_key(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for arg, match in (("colour=3", "--set colour: unknown material parameter; settable: Delta"),
                       ("eta0=none", "--set eta0 = none: eta0 needs a number"),
                       ("eta0=abc", "--set eta0 = 'abc' is not a number [Pa s]"),
                       ("=5", "--set '=5': empty name or value"),
                       ("K0=", "--set 'K0=': empty name or value"),
                       ("K0", "--set expects NAME=VALUE, got 'K0'")):
        # fit parses NAME=VALUE with the same function (it checks the key once files are read)
        parse_only = arg in ("=5", "K0=", "K0")
        for cmd in (["flow-curve"],) + ((["fit", "x.csv", "--phi", "0.4"],) if parse_only else ()):
            with pytest.raises(SystemExit) as exc:
                main([*cmd, "--set", arg])
            err = capsys.readouterr().err
            assert exc.value.code == 2 and err.count("\n") == 1 and match in err, err
    assert not any(tmp_path.iterdir())


def test_phi_help_states_the_default_the_run_uses():
    """Each command's --phi help names the fractions a run without --phi uses (relax said 0.52
    and ran at 0.50; program said 0.46): the help is generated from rheology.materials."""
    import argparse
    import re

    from rheometer.cli import build_parser
    from rheometer.options import DEFAULT_MATERIAL, sample_material

    ap = build_parser()
    sub = next(a for a in ap._actions if isinstance(a, argparse._SubParsersAction))
    checked = []
    for name, sp in sub.choices.items():
        if "_phi_count" not in sp._defaults:          # read/fit: --phi labels data files
            continue
        helptext = next(a.help for a in sp._actions if "--phi" in a.option_strings)
        stated = [float(x) for x in
                  re.search(rf"{DEFAULT_MATERIAL}: ([0-9. ]+)\)", helptext).group(1).split()]
        args = ap.parse_args([name, "x.txt"] if name == "program" else [name])
        phi = sample_material(args).phi                      # the defaults without --phi
        assert phi == pytest.approx(stated), (name, helptext, phi)
        checked.append(name)
    assert {"flow-curve", "startup", "creep", "relax", "program", "material-point",
            "oscillation"} <= set(checked)


def test_creep_at_zero_stress_is_refused(tmp_path, monkeypatch, capsys):
    """A creep from rest at zero imposed stress never leaves rest (no test at all): --stress is
    in [1e-12, 1e12] Pa (runkit.limits' stresses); one line, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    assert main(["creep", "--stress", "0"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "--stress = 0 is outside the valid range [1e-12, 1e+12] Pa (the stress water" in err
    assert not any(tmp_path.iterdir())


def test_elastic_strain_past_the_small_strain_limit_ends_the_run_there(tmp_path, monkeypatch,
                                                                      capsys):
    """startup --rate 1e9 wrote a granular stress of 1e13 Pa (taubar/G ~ 1e9 with G = 1e4 Pa).
    The hypoelastic law holds for elastic strains taubar/G <= 0.1 (rheology.elastic, shear1d's
    bound): the run ends on the limit (rheology.run_end), its rows up to it written, one line
    naming the limit, the time, what to change; exit 3. relax --stress past 0.1 G is known up
    front: exit 2, nothing written."""
    import json

    from rheology.elastic import ELASTIC_STRAIN_LIMIT

    monkeypatch.chdir(tmp_path)
    for argv in (["startup", "--rate", "1e9", "--t-end", "1", "--points", "5"],
                 ["creep", "--stress", "1e5", "--t-end", "1", "--points", "5"],
                 ["material-point", "--rate", "1e3", "--t-end", "1"]):
        assert main(argv) == 3, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and f"rheometer {argv[0]}: phi = 0.5: ended early at t = " \
            in err and "small-elastic-strain limit 0.1" in err and "--G" in err, err
        name = argv[0].replace("-", "_")
        df = pd.read_csv(f"{name}.csv")
        assert df["granular_shear_stress_Pa"].abs().max() <= 1e3 * (1 + 1e-6)
        rec = json.loads(open(f"{name}.json").read())
        assert rec["status"] == "ended_early" and rec["rows"] == len(df)
        (end,) = rec["ends"]
        assert end["kind"] == "validity_limit" and end["limit"] == ELASTIC_STRAIN_LIMIT
        assert end["time_s"] == pytest.approx(df["time_s"].iloc[-1], rel=1e-12)
    before = sorted(os.listdir(tmp_path))
    assert main(["relax", "--stress", "2000", "--t-end", "1"]) == 2
    err = capsys.readouterr().err
    assert "--stress = 2000 is outside the valid range [1e-12, 1000] Pa (the steady state" in err \
            and "--G" in err
    assert sorted(os.listdir(tmp_path)) == before
    # at the limit and with a stiffer skeleton the same inputs run to their end
    assert main(["relax", "--stress", "1000", "--t-end", "1", "--points", "5",
                 "--plot", "none"]) == 0
    assert main(["relax", "--stress", "2000", "--G", "1e5", "--t-end", "1", "--points", "5",
                 "--plot", "none"]) == 0
    df = pd.read_csv("relax.csv")
    assert df["granular_shear_stress_Pa"].abs().max() <= ELASTIC_STRAIN_LIMIT * 1e5 * (1 + 1e-6)
    assert df["time_s"].iloc[-1] == 1.0
    assert json.loads(open("relax.json").read()) == {"status": "complete", "ends": [],
                                                     "command": "rheometer relax",
                                                     "csv": "relax.csv", "rows": len(df)}


def test_python_api_follows_large_strains_unless_asked():
    """The Python functions follow the law's algebra to large strains by default (validation of
    the Jaumann relations); elastic_limit=True applies the command line's check."""
    from rheometer import startup

    df = startup("hermes2016", 0.50, 1.0, 6.0, points=20)
    assert df["granular_shear_stress_Pa"].max() > 0.1 * df.attrs["G_Pa"]
    with pytest.raises(RuntimeError, match="elastic strain taubar/G"):
        startup("hermes2016", 0.50, 1.0, 6.0, points=20, elastic_limit=True)


def test_past_elastic_limit_unit():
    from rheology.elastic import past_elastic_limit

    assert past_elastic_limit([0, 1], [0.0, 1000.0], 1e4) is None   # exactly at the limit
    i, end = past_elastic_limit(np.array([0.0, 1.0, 2.0]), [0.0, 0.0, -2e3], 1e4,
                                stress_name="p", modulus_name="K")
    assert i == 2 and end.kind == "validity_limit" and end.quantity == "elastic strain p/K"
    assert (end.time_s, end.past_s, end.value, end.limit) == (1.0, 2.0, 0.2, 0.1)
    assert "p/K = 0.2 at t = 2 s" in end.reason and "from t ~ 1.5 s" in end.reason
    assert past_elastic_limit([0.0], [2e3], 1e4)[1].time_s is None    # no row before it


# ------------------------------------------------------------------ fresh-user faults 8 and 12
@pytest.mark.parametrize("argv, first, valid", [
    # the step count t_end/dt: named by --dt (its value) with the smallest valid --dt at this
    # --t-end (10 s / 2e7 = 5e-7 s), and the longest --t-end at this --dt
    (["--dt", "1e-7"], "--dt = 1e-07 s gives 1e+08 local updates to --t-end = 10 s",
     "valid: --dt >= 5e-07 s at this --t-end, or --t-end <= 2 s at this --dt"),
    (["--dt", "1e-11"], "--dt = 1e-11 s gives 1e+12 local updates", "--dt >= 5e-07 s"),
    (["--dt", "1e-6", "--t-end", "100"], "--dt = 1e-06 s gives 1e+08 local updates to --t-end "
     "= 100 s", "--dt >= 5e-06 s at this --t-end, or --t-end <= 20 s at this --dt"),
    # the strain rate x t_end at <= 0.01 per update: no --dt helps; --t-end and --rate named
    (["--rate", "1e6", "--t-end", "1000"], "--t-end = 1000 s at --rate = 1e+06 1/s is a shear "
     "strain of 1e+09", "valid: --t-end <= 0.2 s at this --rate, or --rate <= 200 1/s"),
    # a step longer than the run: named as --dt (was 'dt [s]')
    (["--dt", "100"], "--dt = 100 is outside the valid range [1e-12, 10] s", "--t-end = 10 s"),
])
def test_material_point_update_count_names_its_options(argv, first, valid, tmp_path,
                                                        monkeypatch, capsys):
    """Fault 8: a too-small --dt was refused with a message about t_end's strain (whose
    suggested limit was already satisfied); now the options that set the count are named, with
    values that pass."""
    monkeypatch.chdir(tmp_path)
    assert main(["material-point", *argv]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and first in err[0] and valid in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_material_point_suggested_dt_passes_the_check():
    """The smallest --dt the refusal states is accepted, a slightly smaller one refused (by the
    one check of the command line and the Python API, rheometer.material_point.check_drive)."""
    from rheometer.cli import _POINT_LABELS
    from rheometer.material_point import MAX_SUBSTEPS, check_drive

    for t_end in (10.0, 3.7, 1e3):
        dt = t_end / MAX_SUBSTEPS
        assert check_drive(0.5, t_end, dt, _POINT_LABELS.get) == (0.5, t_end, dt)
        with pytest.raises(ValueError, match="--dt = "):
            check_drive(0.5, t_end, dt / 1.01, _POINT_LABELS.get)
        with pytest.raises(ValueError, match="^dt = "):       # the API: its parameter's name
            check_drive(0.5, t_end, dt / 1.01)


def test_material_point_options_are_checked_once(tmp_path, monkeypatch, capsys):
    """--rate, --t-end, --dt, --points are read by the parser (a finite number) and checked once,
    by simple_shear_point's check_drive, named as the options; the Python API refuses the same
    values naming its parameters."""
    import rheometer.material_point as mp
    from rheometer import simple_shear_point

    calls = []
    real = mp.check_drive
    monkeypatch.setattr(mp, "check_drive", lambda *a: calls.append(a) or real(*a))
    monkeypatch.chdir(tmp_path)
    for argv, words in ((["--rate", "-1"], "--rate = -1 is outside the valid range [1e-09, "
                                           "1e+09] 1/s, or 0"),
                        (["--t-end", "0"], "--t-end = 0 is outside the valid range [1e-12, "
                                           "1e+09] s"),
                        (["--dt", "1e300"], "--dt = 1e+300 is outside the valid range [1e-12, "
                                            "1e+09] s (30 years"),
                        (["--points", "0"], "--points = 0 is outside the valid range [1, 1e+07]")):
        calls.clear()
        assert main(["material-point", *argv]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
        assert len(calls) <= 1                           # one check (--points: after it)
        assert list(tmp_path.iterdir()) == []
    for kwargs, words in ((dict(rate=1e12), "rate = 1e+12 is outside"),
                          (dict(t_end=-1.0), "t_end = -1 is outside"),
                          (dict(dt=float("nan")), "dt = nan: must be finite"),
                          (dict(points=0), "points = 0 is outside")):
        args = dict(rate=1.0, t_end=1.0, dt=1e-2) | kwargs
        with pytest.raises(ValueError, match="^" + re.escape(words)):
            simple_shear_point(HERMES, 0.5, args.pop("rate"), args.pop("t_end"), args.pop("dt"),
                               **args)


def test_resume_names_the_checkpoint_actually_read(tmp_path, monkeypatch, capsys):
    """Fault 12: with NAME.checkpoint.npz corrupt, the run resumes from NAME.checkpoint.prev.npz
    (said on stderr) and the final message names that file, not the corrupt one."""
    from rheometer.checkpoint import ProgramCheckpoint

    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.txt").write_text("rest for 0.1 s\nrest for 0.1 s\nshear at 0.1 1/s for 0.1 s\n")
    argv = ["program", "p.txt", "--phi", "0.48", "--plot", "none", "--out", "part.csv",
            "--checkpoint-every", "1e-9"]
    original, calls = ProgramCheckpoint._on_step, {"n": 0}

    def on_step(self, progress):
        original(self, progress)                        # saved after every step
        calls["n"] += 1
        if calls["n"] == 2:
            raise KeyboardInterrupt
    monkeypatch.setattr(ProgramCheckpoint, "_on_step", on_step)
    assert main(argv) == 130
    monkeypatch.undo()
    monkeypatch.chdir(tmp_path)
    assert (tmp_path / "part.checkpoint.prev.npz").is_file()
    (tmp_path / "part.checkpoint.npz").write_bytes(b"not a zip")
    capsys.readouterr()
    assert main(argv + ["--resume"]) == 0
    cap = capsys.readouterr()
    assert "resuming from the previous checkpoint part.checkpoint.prev.npz" in cap.err
    assert "resumed from part.checkpoint.prev.npz" in cap.out, cap.out
    assert "resumed from part.checkpoint.npz" not in cap.out
    assert pd.read_csv(tmp_path / "part.csv")["step"].max() == 3


def test_startup_far_past_the_elastic_limit_names_it_when_ida_gives_up(tmp_path, monkeypatch,
                                                                       capsys):
    """--rate 1e9 --t-end 1e9 (both in range): IDA gave up at taubar 1e20 Pa before the elastic
    strain check ran, and the failure said only 'IDA failed'. The run now ends on the limit
    itself (a root of |taubar| - 0.1 G): one line naming it, the rows up to it, exit 3."""
    monkeypatch.chdir(tmp_path)
    assert main(["startup", "--rate", "1e9", "--t-end", "1e9"]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the small-elastic-strain limit 0.1" in err[0], err
    df = pd.read_csv("startup.csv")
    tau = df["granular_shear_stress_Pa"].to_numpy()
    assert tau[-1] == pytest.approx(1e3, rel=1e-9) and np.all(tau <= 1e3 * (1 + 1e-9))


# ------------------------------------------------------------------ every option's physical range
def _numeric_options():
    """(subcommand, option) of every rheometer option whose value is a quantity with a unit
    (plus the strain amplitude and the volume fraction, dimensionless quantities with physical
    limits), walked from the parser: an option added later is covered the day it is added."""
    import argparse

    from rheometer.cli import build_parser
    from runkit.params import Option

    out = []
    for action in build_parser()._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, sp in action.choices.items():
                for a in sp._actions:
                    if isinstance(a.type, Option) and (a.type.param.unit or a.option_strings[-1]
                                                       in ("--strain-amplitude", "--phi")):
                        out.append((sub, a.option_strings[-1]))
    return out


#: what a subcommand or option needs besides the value under test (a dimension of a geometry is
#: checked with the geometry's other dimensions)
_NEEDS = {"read": ["data.csv"], "fit": ["data.csv"],
          "fit-relaxation": ["data.csv", "--material", "hermes2016", "--phi", "0.5",
                             "--stress0", "10"]}
_GEOMETRY = {"--cone-angle": "cone-plate", "--gap": "parallel-plate", "--bob-radius": "couette",
             "--cup-radius": "couette", "--bob-length": "couette"}
def _option_cases():
    cases = []
    for sub, opt in _numeric_options():
        for value in ("1e-300", "1e300", "nan"):
            if opt == "--time-offset" and value == "1e-300":
                continue            # a signed time on the curve's clock: 0 (and 1e-300) valid
            cases.append(pytest.param(sub, opt, value, id=f"{sub} {opt} {value}"))
    return cases


@pytest.mark.parametrize("sub, option, value", _option_cases())
def test_every_dimensional_option_is_refused_at_its_physical_range(sub, option, value, tmp_path,
                                                                   monkeypatch, capsys):
    """1e-300, 1e300 and nan of every dimensional option of every subcommand: exit 2, one line
    naming the option with its physical range (never (-inf, inf)) and the reason, nothing on
    stdout, nothing written (fresh-user findings 4, 8, 12, 15, 16)."""
    import re

    monkeypatch.chdir(tmp_path)
    argv = [sub, *_NEEDS.get(sub, [])]
    if option in _GEOMETRY:
        argv += ["--geometry", _GEOMETRY[option]]
    elif option == "--radius":
        argv += ["--geometry", "cone-plate"]
    if option == "--stress-amplitude":
        argv += ["--control", "stress"]
    argv += [option, value] + ([value] if option.endswith("-range") else [])   # LO HI
    try:
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and not out, (argv, rc, out, err)
    assert f"{option} = " in lines[0], lines[0]
    assert "(-inf" not in lines[0] and ", inf)" not in lines[0], lines[0]
    # the range, then its reason in brackets: "[1e-06, 1) (one grain volume ..."
    said = re.sub(r" \(see rheometer [\w-]+ --help\)$", "", lines[0])   # argparse's pointer
    assert re.search(r"valid range [\[(][^\])]*[\])][^(]*\(.*[a-zA-Z]{3}", said), lines[0]
    assert not any(tmp_path.iterdir())


def test_a_refused_fit_prints_only_its_one_line(tmp_path, monkeypatch, capsys):
    """Before: 'read 1 curve(s) ...' and 'skipped ...' on stdout before the one-line error."""
    from pathlib import Path

    example = Path(__file__).parents[1] / "rheometer" / "examples" / "rheocompass_phi_0.40.csv"
    monkeypatch.chdir(tmp_path)
    rc = main(["fit", str(example), "--phi", "0.6"])
    out, err = capsys.readouterr()
    assert rc == 2 and out == "" and len(err.strip().splitlines()) == 1, (out, err)
    assert not any(tmp_path.iterdir())


def test_material_point_end_time_and_reason_agree(tmp_path, monkeypatch, capsys):
    """Before: 'ended early at t = 0 s ... taubar/G = 0.1 at t = 10 s ... past the limit from t
    ~ 9.966 s': the end row and the crossing between the rows are now said together, the strain
    at digits that tell it from the limit."""
    monkeypatch.chdir(tmp_path)
    assert main(["material-point", "--rate", "1", "--dt", "10", "--plot", "none"]) == 3
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "ended early at t = 0 s (last row written)" in err
    assert "taubar/G = 0.1003 at t = 10 s" in err
    assert "the run ends at the row before, t = 0 s, the last within the limit" in err
    assert "between these rows, from t ~ 9.966 s" in err


@pytest.mark.parametrize("argv, words", [
    (["startup", "--t-end", "0"], "--t-end = 0 is outside the valid range [1e-12, 1e+09] s (1 ps"),
    (["creep", "--t-end", "1e300"], "--t-end = 1e+300 is outside the valid range [1e-12, 1e+09] "
                                    "s (30 years"),
    (["relax", "--rtol", "1"], "--rtol = 1 is outside the valid range [1e-13, 0.01] (looser"),
    (["startup", "--points", "2"], "--points = 2 is outside the valid range [3, 1e+06] (a "
                                   "step's start"),
    (["program", "--rtol", "1e-20"], "--rtol = 1e-20 is outside the valid range [1e-13, 0.01]"),
    (["material-point", "--f0", "2"], "--f0 = 2 is outside the valid range [0, 1] (f is a "
                                      "fraction)"),
])
def test_transient_options_are_checked_once_by_the_run(argv, words, tmp_path, monkeypatch,
                                                       capsys):
    """--t-end, --rtol, --points of the transients (and --f0 of material-point) were checked
    by the parser and again by Step / Rheometer (initial_point) with the same bounds; now the
    parser reads a finite number (the value passes it) and the run checks its range once,
    named as the option (no argparse frame), before anything is written."""
    from rheometer.cli import build_parser

    build_parser().parse_args(argv)                        # read, not range-checked, here
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "argument " not in err[0], err
    assert list(tmp_path.iterdir()) == []
