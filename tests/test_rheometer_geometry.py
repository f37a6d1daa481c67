"""Measuring geometries (standard conversions, the parallel plate's radial integration and the
Weissenberg-Rabinowitsch correction), Eq. (20) mass fractions, per-material defaults and
normalised column names."""

import math

import numpy as np
import pandas as pd
import pytest

import rheology
from rheology import materials as mat, sample
from rheometer import geometry as geo

HERMES = rheology.get_material("hermes2016")


def test_cone_plate_and_couette_conversions():
    cp = geo.Geometry.make("cone-plate", cone_angle_deg=1.0, radius=0.025)
    M = cp.torque(100.0)
    assert M == pytest.approx(2 * math.pi * 0.025 ** 3 * 100.0 / 3, rel=1e-15)   # 3.27e-3 N m
    assert cp.rotation_speed(10.0) == pytest.approx(10.0 * math.tan(math.radians(1.0)), rel=1e-15)
    cc = geo.Geometry.make("couette", bob_radius=0.01333, cup_radius=0.01446, bob_length=0.04)
    assert cc.torque(10.0) == pytest.approx(2 * math.pi * 0.01333 ** 2 * 0.04 * 10.0, rel=1e-15)
    assert cc.rotation_speed(5.0) == pytest.approx(
        5.0 * (0.01446 ** 2 - 0.01333 ** 2) / (2 * 0.01446 ** 2), rel=1e-14)
    for g in (cp, cc, geo.Geometry.make("parallel-plate")):
        s, r = g.apparent(g.torque([1.0, 50.0]), g.rotation_speed([0.1, 3.0]))
        assert np.allclose(s, [1.0, 50.0], rtol=1e-14) and np.allclose(r, [0.1, 3.0], rtol=1e-14)
    df = geo.instrument_columns(pd.DataFrame({"shear_stress_Pa": [2.0], "shear_rate_per_s": [4.0]}),
                                cp)
    assert list(df.columns[-4:]) == list(geo.INSTRUMENT_COLUMNS)


def test_geometry_bad_dimensions():
    with pytest.raises(ValueError, match="cup radius"):
        geo.Geometry.make("couette", bob_radius=0.02, cup_radius=0.01)
    with pytest.raises(ValueError, match="cone angle"):
        geo.Geometry.make("cone-plate", cone_angle_deg=20.0)
    with pytest.raises(ValueError, match="geometry"):
        geo.Geometry.make("vane")


def test_parallel_plate_newtonian_limit_and_dst_difference():
    plate = geo.Geometry.make("parallel-plate", radius=0.0125, gap=0.001)
    df = geo.parallel_plate_flow_curve(HERMES, 0.50, plate)
    assert df.attrs["fold_reached"]
    rel = df["apparent_shear_stress_Pa"] / df["shear_stress_Pa"] - 1
    low = df["shear_stress_Pa"] < 1e-4 * HERMES.tau_star       # Newtonian plateau: n = 1
    assert low.sum() > 100 and np.abs(rel[low]).max() < 1e-5
    assert rel.min() < -0.3                  # DST: the plate's average lags the rim by > 30%
    # torque from the radial integral, checked against a direct quadrature in r
    i = int(0.9 * len(df))
    gR = df["rim_shear_rate_per_s"].iloc[i]
    branch, _ = geo.rising_branch(HERMES, 0.50, 4000)
    r = np.linspace(0, 1, 2001)[1:]
    sig = np.interp(gR * r, branch.shear_rate, branch.shear_stress)
    M = 2 * math.pi * plate.radius ** 3 * np.trapezoid(np.r_[0, sig * r ** 2], np.r_[0, r])
    assert df["torque_N_m"].iloc[i] == pytest.approx(M, rel=1e-4)


@pytest.mark.parametrize("phi", [0.42, 0.50])
def test_weissenberg_rabinowitsch_recovers_the_true_curve(phi):
    df = geo.parallel_plate_flow_curve(HERMES, phi)
    err = np.abs(df["corrected_shear_stress_Pa"] / df["shear_stress_Pa"] - 1).to_numpy()
    app = np.abs(df["apparent_shear_stress_Pa"] / df["shear_stress_Pa"] - 1).to_numpy()
    inner = slice(1, len(df) - 3)            # finite differences one-sided at the ends
    assert np.max(err[inner]) < 2e-3 and np.median(err) < 1e-6
    assert np.max(app) > 100 * np.max(err[inner])


def test_mass_fraction_eq20():
    d = sample.Densities()
    w = np.array([0.3, 0.44, 0.55])
    phi = sample.volume_fraction(w, d)
    expect = (1.3 * 0.9) / (0.9 + (1 - w) / w * 1620 / 1000 + 0.1 * 1620 / 1000)   # Eq. (20)
    assert np.allclose(phi, expect, rtol=1e-15)
    assert np.allclose(sample.mass_fraction(phi, d), w, rtol=1e-13)
    assert sample.Densities.for_material(rheology.get_material("annular_shear")).liquid == 1620.0
    with pytest.raises(ValueError, match="--mass-fraction"):
        sample.fractions_from_mass([0.7], HERMES, d)          # phi above phi_j
    with pytest.raises(ValueError, match="--mass-fraction"):
        sample.fractions_from_mass([1.5], HERMES, d)


def test_default_fractions_rule():
    assert mat.default_fractions("hermes2016") == [0.48, 0.50, 0.52]
    assert mat.default_fraction("hermes2016") == 0.50
    for name in rheology.materials.material_names():
        m = rheology.get_material(name)
        phis = mat.default_fractions(m)
        assert phis == sorted(phis) and len(set(phis)) == 3
        if mat.has_dst(m):
            assert all(m.phi_c <= p < m.phi_j for p in phis), name
        else:
            assert all(0 < p < m.phi_c for p in phis), name
        fc = rheology.steady_state_stress(np.logspace(-3, 3, 20) * m.tau_star, phis[1], m)
        assert np.all(np.isfinite(fc.shear_stress))


def test_normalised_columns():
    df = pd.DataFrame(columns=["time_s", "shear_stress_Pa", "shear_rate_per_s", "viscosity_Pa_s",
                               "frequency_Hz", "torque_N_m", "phi", "f"])
    out = geo.normalise_columns(df, "singh2018_a")
    assert list(out.columns) == ["time_per_gdot0", "shear_stress_eta0_gdot0", "shear_rate_gdot0",
                                 "viscosity_eta0", "frequency_gdot0", "torque_eta0_gdot0_m3",
                                 "phi", "f"]
    assert list(geo.normalise_columns(df, "hermes2016").columns) == list(df.columns)


# ------------------------------------------------------------------ the command line
def test_cli_mass_fraction_and_cone_plate(tmp_path, monkeypatch, capsys):
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve", "--mass-fraction", "0.55", "0.57", "--geometry", "cone-plate",
                 "--radius", "0.02", "--cone-angle", "2", "--points", "20", "--plot",
                 "none"]) == 0
    out = capsys.readouterr().out
    phi = sample.volume_fraction(np.array([0.55, 0.57]), sample.Densities())
    assert "mass fraction 0.55, 0.57 -> phi = " in out and "cone-plate" in out
    df = pd.read_csv("flow_curve.csv")
    assert np.allclose(sorted(df["phi"].unique()), phi, rtol=1e-12)
    assert set(df["mass_fraction"].round(12)) == {0.55, 0.57}
    R, a = 0.02, math.radians(2.0)
    assert np.allclose(df["torque_N_m"], 2 * math.pi * R ** 3 * df["shear_stress_Pa"] / 3,
                       rtol=1e-13)
    assert np.allclose(df["rotation_speed_rad_per_s"], df["shear_rate_per_s"] * math.tan(a),
                       rtol=1e-13)
    assert np.allclose(df["apparent_shear_stress_Pa"], df["shear_stress_Pa"], rtol=1e-13)


def test_cli_parallel_plate_flow_curve_writes_both_curves(tmp_path, monkeypatch):
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve", "--phi", "0.5", "--geometry", "parallel-plate", "--points",
                 "40"]) == 0
    df = pd.read_csv("flow_curve.csv")
    pp = pd.read_csv("flow_curve_parallel_plate.csv")
    assert (tmp_path / "flow_curve_parallel_plate.png").stat().st_size > 10_000
    assert {"apparent_shear_stress_Pa", "corrected_shear_stress_Pa"} <= set(pp.columns)
    beyond = df["granular_shear_stress_Pa"] > pp["granular_shear_stress_Pa"].max()
    assert beyond.any() and df.loc[beyond, "torque_N_m"].isna().all()   # no plate-wide state
    assert df.loc[~beyond, "torque_N_m"].notna().all()


@pytest.mark.parametrize("argv, words", [
    (["flow-curve", "--gap", "0.001"], "--gap needs --geometry"),
    (["flow-curve", "--geometry", "cone-plate", "--gap", "0.001"], "not a dimension"),
    (["flow-curve", "--mass-fraction", "0.9"], "--mass-fraction = 0.9"),
    (["flow-curve", "--mass-fraction", "0.5", "--phi", "0.5"], "--phi or --mass-fraction"),
    (["startup", "--phi", "0.6"], "--phi = 0.6"),
    (["flow-curve", "--geometry", "couette", "--bob-radius", "0.02"], "cup radius"),
])
def test_cli_instrument_bad_input(tmp_path, monkeypatch, capsys, argv, words):
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1
    assert not list(tmp_path.iterdir())                 # nothing written


@pytest.mark.parametrize("phi_j", [0.45, 0.44, 0.438, 0.5])
def test_default_fractions_stay_distinct_in_a_narrow_dst_window(phi_j):
    """A phi_j set close to phi_c: rounding to 0.005 would merge the fractions (phi_j = 0.45 gave
    0.44, 0.445, 0.445: one curve twice); a finer rounding keeps three distinct fractions in
    the DST window phi_c <= phi < phi_j."""
    m = rheology.get_material("hermes2016", phi_j=phi_j)
    phis = mat.default_fractions(m)
    assert phis == sorted(phis) and len(set(phis)) == 3, phis
    assert all(m.phi_c <= p < m.phi_j for p in phis), phis


def test_a_sets_own_phi0_follows_a_phi_j_set_below_it():
    """annular_shear's phi0 = 0.505 with --set phi_j = 0.45: the set's own initial fraction
    follows the default-fraction rule (was: a refusal naming phi0 = 0.505, a value the user
    never gave); a phi0 given with it is checked as given."""
    m = rheology.get_material("annular_shear", phi_j=0.45)
    assert m.phi0 == mat.default_fraction(m) < 0.45
    assert rheology.get_material("annular_shear", phi_j=0.52).phi0 == 0.505     # still below
    with pytest.raises(ValueError, match="phi0"):
        rheology.get_material("annular_shear", phi_j=0.45, phi0=0.46)
