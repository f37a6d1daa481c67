"""Readers of measured flow curves (rheology.data) and `rheometer read`."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import rheology as r
from rheology.data import (COLUMNS, DROP_REASONS, Curve, block_curve, clean, drop_counts,
                           read_blocks, read_flow_curves, read_relaxation_curves, select_blocks,
                           stress_constant, to_number, unit_factor, write_export,
                           write_rheocompass)
from rheometer.cli import main

FIX = Path("/work/shared/fixtures/rheocompass")
FILES = sorted(FIX.glob("synthetic_phi_*.csv")) if FIX.is_dir() else []
PHIS = [0.38, 0.41, 0.44, 0.47, 0.50]
needs_fixtures = pytest.mark.skipif(len(FILES) != 5, reason="shared fixtures not present")


@needs_fixtures
def test_fixtures_read_viscosity_curve_only_and_drop_torque_floor():
    t = read_flow_curves(FILES, phi=PHIS)
    assert list(t.columns) == list(COLUMNS)
    assert set(t["interval"]) == {"Viscosity curve 1 (interval 2)"}       # pre-shear kept out
    per = t.groupby("phi")
    assert (per.size() == 41).all() and (per["kept"].sum() == 39).all()
    assert drop_counts(t) == {"below_torque_floor": 10}
    k = t[t["kept"]]
    # the instrument's viscosity column is stress/rate (5 significant digits in the file)
    assert np.allclose(k["viscosity_Pa_s"], k["shear_stress_Pa"] / k["shear_rate_per_s"],
                       rtol=2e-4)
    # stress ramp 0.01-1000 Pa, log-spaced
    s = t[t["phi"] == 0.44]["shear_stress_Pa"].to_numpy()
    assert s[0] == pytest.approx(0.01) and s[-1] == pytest.approx(1000.0)
    assert np.all(np.diff(s) > 0)


@needs_fixtures
def test_interval_selection_by_name_and_unknown_name_lists_blocks():
    fmt, blocks = read_blocks(FILES[0])
    chosen, skipped = select_blocks(blocks, "flow", ["preshear"], fmt, FILES[0].name)
    pre = block_curve(chosen[0], str(FILES[0]))
    assert fmt == "rheocompass" and len(chosen) == 1 and np.all(pre.shear_rate == 10)
    assert pre.shear_stress.size == 5
    assert skipped == [("Viscosity curve 1 (interval 2)", "not named like 'preshear'")]
    # by default the pre-shear is listed as skipped, with its reason
    t = read_flow_curves(FILES[:1], phi=[0.4])
    assert t.attrs["skipped"] == [(FILES[0].name, "Preshear 1 (interval 1)",
                                   "conditioning or pre-shear")]
    with pytest.raises(ValueError, match="Preshear 1.*Viscosity curve 1"):
        read_flow_curves(FILES[:1], phi=[0.4], intervals=["amplitude sweep"])


def _roundtrip(tmp_path, stress, rate, status=None):
    p = tmp_path / "export.txt"
    write_rheocompass(p, [{"name": "Preshear", "stress": [5.0] * 3, "rate": [1.0] * 3},
                          {"name": "Flow curve 1", "stress": stress, "rate": rate,
                           "status": status}])
    return p


def test_artefacts_dropped_with_a_reason_each(tmp_path):
    s = np.array([0.1, 0.2, 0.2, 0.4, 0.3, 0.8, 1.6, 3.2, 6.4])
    g = np.array([-1.0, 2.0, 2.0, 4.0, 3.0, np.nan, 16.0, -4.0, 64.0])
    status = ["Dy_auto,ME-"] + ["Dy_auto"] * 8
    p = _roundtrip(tmp_path, s, g, status)
    assert p.read_bytes()[:2] == b"\xff\xfe"                             # UTF-16 like RheoCompass
    t = read_flow_curves([p], phi=[0.4])
    reasons = list(t["dropped_reason"])
    assert reasons == ["below_torque_floor", "", "duplicate", "", "non_monotone",
                       "missing_value", "", "nonpositive_rate", ""]
    assert set(drop_counts(t)) <= set(DROP_REASONS)
    assert t["kept"].sum() == 4


def test_no_usable_curve_names_the_file(tmp_path):
    p = _roundtrip(tmp_path, [0.1, 0.2, 0.4], [-1.0, -2.0, -3.0])
    with pytest.raises(ValueError, match="export.txt.*no usable flow curve"):
        read_flow_curves([p], phi=[0.4])


def test_missing_phi_is_an_error_naming_the_file(tmp_path):
    p = _roundtrip(tmp_path, [0.1, 0.2, 0.4, 0.8], [1.0, 2.0, 4.0, 8.0])
    with pytest.raises(ValueError, match="export.txt.*--phi"):
        read_flow_curves([p])
    assert read_flow_curves([p], require_phi=False)["phi"].isna().all()


def test_table_with_mapping_units_and_phi_column(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("sample;tau (mPa);visc [mPa·s];note\n0.40;100;50;a\n0.40;200;50;b\n0.40;400;"
                 "40;c\n0.45;100;80;\n0.45;200;85;\n0.45;400;90;\n", encoding="utf-8")
    t = read_flow_curves([p], columns={"stress": "tau", "viscosity": "visc", "phi": "sample"})
    assert sorted(t["phi"].unique()) == [0.40, 0.45]
    row = t.iloc[0]
    assert row["shear_stress_Pa"] == pytest.approx(0.1)                 # mPa -> Pa
    assert row["viscosity_Pa_s"] == pytest.approx(0.05)                 # mPa s -> Pa s
    assert row["shear_rate_per_s"] == pytest.approx(2.0)                # completed: stress/visc
    with pytest.raises(ValueError, match="--columns stress='sigma' is not a column"):
        read_flow_curves([p], columns={"stress": "sigma", "viscosity": "visc", "phi": "sample"})
    with pytest.raises(ValueError, match="phi column and --phi"):
        read_flow_curves([p], columns={"stress": "tau", "viscosity": "visc", "phi": "sample"},
                         phi=[0.4])


def test_mass_fraction_converted_with_eq20(tmp_path):
    p = _roundtrip(tmp_path, [0.1, 0.2, 0.4, 0.8], [1.0, 2.0, 4.0, 8.0])
    mf = dict(rho_cs=1630.0, rho_l=1000.0)
    t = read_flow_curves([p], phi=[0.5], mass_fraction=mf)
    assert t["phi"].iloc[0] == pytest.approx(float(r.phi_from_mass_fraction(0.5, 1630.0, 1000.0)))
    assert 0 < t["phi"].iloc[0] < 0.5


def test_numbers_exponent_and_decimal_comma():
    assert to_number("1.5E-03") == 1.5e-3 and to_number("2,5") == 2.5
    assert np.isnan(to_number("")) and np.isnan(to_number("Dy_auto"))


def test_down_ramp_is_monotone_too():
    c = Curve("f", "i", np.arange(4.0), np.zeros(4), np.array([8.0, 4.0, 5.0, 1.0]),
              np.array([8.0, 4.0, 5.0, 1.0]), np.ones(4))
    kept, why = clean(c)
    assert list(why) == ["", "", "non_monotone", ""]


@needs_fixtures
def test_cli_read_writes_tidy_csv_and_refuses_bad_phi(tmp_path, capsys):
    out = tmp_path / "curves.csv"
    assert main(["read", *map(str, FILES), "--phi", *map(str, PHIS), "--out", str(out)]) == 0
    df = pd.read_csv(out)
    assert list(df.columns) == list(COLUMNS) and len(df) == 205
    assert "below_torque_floor: 10" in capsys.readouterr().out
    bad = tmp_path / "bad.csv"
    assert main(["read", *map(str, FILES), "--phi", "0.4", "--out", str(bad)]) == 2
    with pytest.raises(SystemExit) as exc:                           # argparse: one line, 2
        main(["read", *map(str, FILES), "--phi", *["0.4"] * 4, "nan", "--out", str(bad)])
    assert exc.value.code == 2 and "--phi = nan" in capsys.readouterr().err
    assert not bad.exists()


# ---------------------------------------------------------------- TRIOS and rSpace exports
EX = Path(__file__).resolve().parents[1] / "rheometer" / "examples"
#: Hand count of each shipped export's flow-curve block (rheometer/examples): 31 rows; rows 1-2
#: have negative rates (below the torque floor), row 17 repeats row 16's stress, row 19 has
#: blank rate and viscosity cells; the other blocks are skipped.
HAND = {"trios_phi_0.42.txt": ("trios", "Flow sweep - 2", 0.42,
                               [("Peak hold - 1", "transient"),
                                ("Amplitude sweep - 3", "oscillatory")]),
        "trios_phi_0.45.csv": ("trios-csv", "Flow sweep - 1", 0.45,
                               [("Frequency sweep - 2", "oscillatory")]),
        "rspace_phi_0.48.csv": ("rspace", "Shear stress ramp", 0.48,
                                [("Pre-shear", "pre-shear"), ("Amplitude sweep", "oscillatory")])}
REASONS = ["nonpositive_rate"] * 2 + [""] * 14 + ["duplicate", "", "missing_value"] + [""] * 12


@pytest.mark.parametrize("name", list(HAND))
def test_instrument_exports_give_the_hand_count(name):
    fmt, block, phi, skipped = HAND[name]
    t = read_flow_curves([EX / name], phi=[phi])
    assert t.attrs["formats"] == {str(EX / name): fmt}
    assert set(t["interval"]) == {block} and list(t["dropped_reason"]) == REASONS
    assert [(b, ) for _, b, _ in t.attrs["skipped"]] == [(b, ) for b, _ in skipped]
    assert all(w in why for (_, _, why), (_, w) in zip(t.attrs["skipped"], skipped))
    # units converted: every layout writes the same ramp 0.01..1000 Pa, 6 s per point
    s = t["shear_stress_Pa"].to_numpy()
    assert s[0] == pytest.approx(0.01) and s[-1] == pytest.approx(1000.0)
    assert np.allclose(t["time_s"], 6.0 * np.arange(1, 32))
    k = t[t["kept"]]
    assert np.allclose(k["viscosity_Pa_s"], k["shear_stress_Pa"] / k["shear_rate_per_s"],
                       rtol=2e-5)


def test_trios_units_by_hand():
    """Row 3 of the TRIOS text's flow sweep: 0.0221222 Pa, 0.139531 1/s, 158.546 mPa.s, 18 s;
    of the TRIOS CSV (kPa, Pa.s, min): 2.21222e-05 kPa, 0.3 min."""
    a = read_flow_curves([EX / "trios_phi_0.42.txt"], phi=[0.42]).iloc[2]
    assert (a["shear_stress_Pa"], a["shear_rate_per_s"], a["viscosity_Pa_s"], a["time_s"]) == \
        pytest.approx((0.0221222, 0.139531, 0.158546, 18.0))
    b = read_flow_curves([EX / "trios_phi_0.45.csv"], phi=[0.45]).iloc[2]
    assert (b["shear_stress_Pa"], b["time_s"]) == pytest.approx((0.0221222, 18.0))


@pytest.mark.parametrize("unit, factor", [("[MPa]", 1e6), ("[mPa]", 1e-3), ("(kPa)", 1e3),
                                          ("[Pa]", 1.0), ("mpa", 1e-3)])
def test_stress_units_mega_is_not_milli(unit, factor):
    assert unit_factor("stress", unit, "x") == factor


def test_units_of_viscosity_torque_fraction_and_stress_constant():
    assert unit_factor("viscosity", "Pa·s", "x") == 1.0 and unit_factor("viscosity", "mPa s",
                                                                        "x") == 1e-3
    assert unit_factor("rate", "s-¹", "x") == 1.0 and unit_factor("rate", "s⁻¹", "x") == 1.0
    assert unit_factor("torque", "µN.m", "x") == 1e-3 and unit_factor("torque", "μN m", "x") == 1e-3
    assert unit_factor("fraction", "%", "x") == 0.01
    assert stress_constant({"stress constant": "59683.1 Pa/N.m"}, "x") == pytest.approx(59683.1)
    assert stress_constant({"stress constant": "0.0596831 Pa/µN.m"}, "x") == pytest.approx(59683.1)
    with pytest.raises(ValueError, match="unit \\[furlong\\] of the stress column"):
        unit_factor("stress", "furlong", "x")
    with pytest.raises(ValueError, match="no 'Stress constant'"):
        stress_constant({}, "step 'Stress relaxation - 2'")


def test_phi_column_in_percent(tmp_path):
    p = tmp_path / "t.csv"
    p.write_text("phi [%],Shear Stress [Pa],Shear Rate [1/s]\n40,1,2\n40,2,3\n40,4,5\n")
    t = read_flow_curves([p])
    assert np.allclose(t["phi"], 0.40)


def test_a_file_in_no_known_layout_names_the_layouts_tried(tmp_path):
    p = tmp_path / "notes.txt"
    p.write_text("just some words\nand more words\n")
    with pytest.raises(ValueError) as exc:
        read_flow_curves([p], phi=[0.4])
    msg = str(exc.value)
    assert "notes.txt" in msg and "none of the known layouts" in msg and "\n" not in msg
    for layout in ("RheoCompass", "TRIOS 'Export to LIMS'", "TRIOS CSV", "rSpace", "plain table"):
        assert layout in msg


def test_cli_read_takes_the_three_layouts(tmp_path, capsys):
    out = tmp_path / "c.csv"
    files = [str(EX / n) for n in HAND]
    assert main(["read", *files, "--phi", "0.42", "0.45", "0.48", "--out", str(out)]) == 0
    df = pd.read_csv(out)
    assert len(df) == 93 and df["kept"].sum() == 81
    text = capsys.readouterr().out
    assert "nonpositive_rate: 6" in text and "skipped rspace_phi_0.48.csv 'Pre-shear'" in text
    # --interval picks a block by name in any export (here the TRIOS peak hold)
    out2 = tmp_path / "hold.csv"
    assert main(["read", files[0], "--phi", "0.42", "--interval", "peak hold", "--out",
                 str(out2)]) == 2               # 5 repeated readings: no usable flow curve
    assert "no usable flow curve" in capsys.readouterr().err


def test_cli_fit_takes_the_three_layouts_with_the_hand_counted_points(tmp_path):
    out = tmp_path / "fit"
    files = [str(EX / n) for n in HAND]
    assert main(["fit", *files, "--phi", "0.42", "0.45", "0.48", "--set", "eta0=0.006",
                 "--out", str(out), "--no-plots", "--no-profile"]) == 0
    fit = pd.read_csv(out / "fit.csv")
    assert fit.groupby("source_file").size().to_dict() == {n: 27 for n in HAND}
    read = pd.read_csv(out / "curves.csv")
    kept = read[read["kept"]]
    assert np.allclose(fit["shear_stress_Pa"], kept["shear_stress_Pa"])
    m = r.get_material(str(out / "material.json"))
    h = r.get_material("hermes2016")
    assert abs(m.phi_j - h.phi_j) < 0.005 and abs(m.phi_c - h.phi_c) < 0.005


# ---------------------------------------------------------------- relaxation curves
def test_trios_relaxation_steps_are_torque_converted_with_the_stress_constant():
    t = read_relaxation_curves([EX / "trios_relaxation_phi_0.52.txt"])
    assert list(t.groupby("curve")["interval"].first()) == ["Stress relaxation - 2",
                                                             "Stress relaxation - 4"]
    assert [w for _, _, w in t.attrs["skipped"]] == ["a transient at one rate or stress, not a "
                                                     "flow curve"] * 2
    # first reading of step 2 by hand: torque 1525.74 uN.m x 0.0596831 Pa/uN.m
    text = (EX / "trios_relaxation_phi_0.52.txt").read_text(encoding="latin-1").splitlines()
    k = text.index("Stress relaxation - 2") + 4
    torque = float(text[k].split("\t")[1])
    assert t["shear_stress_Pa"].iloc[0] == pytest.approx(torque * 0.0596831, rel=1e-6)
    assert t["kept"].all() and (np.diff(t[t["curve"] == 0]["time_s"]) > 0).all()


def test_relaxation_without_stress_constant_says_why(tmp_path):
    p = tmp_path / "r.txt"
    write_export(p, "trios", [{"name": "Stress relaxation - 1", "columns": [
        ("Step time", "s", np.array([0.1, 0.2, 0.4])), ("Torque", "µN.m", np.array([9., 5, 2]))]}],
        {"": {"Filename": "x.tri"}})
    with pytest.raises(ValueError, match="records torque but no stress.*Stress constant"):
        read_relaxation_curves([p])


def test_relaxation_from_rheocompass_interval_and_plain_table(tmp_path):
    t = np.array([0.1, 0.2, 0.2, 0.4, 0.8, 1.6])
    s = np.array([90.0, 70.0, 70.0, 40.0, 0.0, 5.0])
    p = tmp_path / "rc.csv"
    write_rheocompass(p, [{"name": "Viscosity curve 1", "stress": [1.0, 2, 4], "rate": [1.0, 2, 3]},
                          {"name": "Relaxation 1", "stress": s, "rate": np.zeros(6), "time": t}])
    a = read_relaxation_curves([p])
    assert list(a["dropped_reason"]) == ["", "", "duplicate", "", "nonpositive_stress", ""]
    assert a.attrs["skipped"][0][2] == "a flow curve (read by rheometer read and fit)"
    q = tmp_path / "tab.csv"
    q.write_text("time [min],tau [kPa]\n0.01,0.09\n0.02,0.05\n0.04,0.03\n0.08,0.02\n")
    b = read_relaxation_curves([q], columns={"time": "time", "stress": "tau"},
                               stress_floor=25.0)
    assert np.allclose(b["time_s"], [0.6, 1.2, 2.4, 4.8])
    assert np.allclose(b["shear_stress_Pa"], [90, 50, 30, 20])
    assert list(b["dropped_reason"]) == ["", "", "", "below_stress_floor"]
