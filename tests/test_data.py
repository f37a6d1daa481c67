"""Readers of measured flow curves (rheology.data) and `rheometer read`."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import rheology as r
from rheology.data import (COLUMNS, DROP_REASONS, Curve, clean, drop_counts, read_flow_curves,
                           read_rheocompass, to_number, write_rheocompass)

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
    pre = read_rheocompass(FILES[0], intervals=["preshear"])
    assert len(pre) == 1 and pre[0].shear_stress.size == 5 and np.all(pre[0].shear_rate == 10)
    with pytest.raises(ValueError, match="Preshear 1.*Viscosity curve 1"):
        read_rheocompass(FILES[0], intervals=["amplitude sweep"])


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
    from rheometer.cli import main

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
