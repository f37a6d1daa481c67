"""Parameter sets: every set of the paper, its source, overrides and validation."""

import dataclasses

import numpy as np
import pytest

import rheology as r
from rheology.materials import check_set_override, split_set_item


def test_every_paper_set_is_listed_with_a_source():
    names = [n for n, _ in r.list_materials()]
    for n in ["singh2018_a", "singh2018_b", "dhaene1993", "frith1996", "guy2015_a", "guy2015_b",
              "fall2015", "hermes2016", "annular_shear", "rod_impact", "rod_impact_1cp",
              "intruder", "wheel"]:
        assert n in names
    for n, cite in r.list_materials():
        m = r.get_material(n)
        assert m.name == n and len(cite) > 20 and m.citation == cite


@pytest.mark.parametrize("name, row", [
    # Table 2 and 3 rows: phi_c, phi_j, a0, a_inf, tau*, eta0 [Pa s], mu_c, varphi1, alpha1, varphi2, alpha2
    ("dhaene1993", (0.57, 0.65, 1.08, 1.08, 5.21, 0.056, 0.3, 8.83e6, 6, 0, 0)),
    ("frith1996", (0.548, 0.642, 1.08, 1.08, 17.93, 0.130, 0.3, 1.79e11, 12, 4.5, 0.1)),
    ("guy2015_a", (0.56, 0.617, 1.577, 1.577, 423.0, 0.0024, 0.3, 3e6, 5, 9e-2, 0.1)),
    ("guy2015_b", (0.563, 0.610, 1.09, 1.538, 3.5, 0.0024, 0.3, 1.0e6, 6, 0, 0)),
    ("fall2015", (0.38, 0.454, 1.00, 1.00, 0.116, 0.00089, 1.19, 4.0e4, 3, 0, 0)),
    ("hermes2016", (0.436, 0.535, 0.8, 0.8, 5.35, 0.006, 1.19, 1.86e4, 4, 9.3e-3, 0.1)),
])
def test_tables_2_and_3(name, row):
    m = r.get_material(name)
    got = (m.phi_c, m.phi_j, m.a0, m.a_inf, m.tau_star, m.eta0, m.mu_c, m.varphi1, m.alpha1,
           m.varphi2, m.alpha2)
    np.testing.assert_allclose(got, row, rtol=1e-12)
    assert m.Delta == 0 and m.units == "SI"


def test_table_1_normalised_sets():
    a, b = r.get_material("singh2018_a"), r.get_material("singh2018_b")
    for m in (a, b):
        assert (m.phi_c, m.phi_j, m.a0, m.a_inf, m.mu_c, m.eta0, m.Delta) == (
            0.585, 0.65, 0.455, 0.841, 1.0, 1.0, 1.0)
        assert m.units == "normalised"
        np.testing.assert_allclose(r.f_max(np.linspace(0.3, 0.64, 30), m), 1.0)   # Delta = 1
    assert a.tau_star == 1.74 and b.tau_star == 1.44
    assert np.all(np.isinf(r.eta_B(np.linspace(0.3, 0.64, 5), a)))
    phi = np.linspace(0.3, 0.64, 7)
    np.testing.assert_allclose(b.eta0 / r.eta_B(phi, b), 0.254 * (b.phi_j - phi), rtol=1e-12)


def test_scene_sets_tables_4_to_7():
    expect = {  # eta0 [Pa s], rho_s, rho_f, G, K, K0
        "annular_shear": (10e-3, 1620, 1620, 3.8e5, 8.3e5, 0.06),
        "rod_impact": (7e-3, 1620, 1000, 3.8e7, 8.3e7, 1.0),
        "rod_impact_1cp": (1e-3, 1620, 1000, 3.8e7, 8.3e7, 1.0),
        "intruder": (4.6e-3, 1620, 1620, 3.8e7, 8.3e7, 0.2),
        "wheel": (1e-3, 1620, 1620, 3.8e5, 8.3e5, 1.0),
    }
    h = r.get_material("hermes2016")
    for name, row in expect.items():
        m = r.get_material(name)
        np.testing.assert_allclose((m.eta0, m.rho_s, m.rho_f, m.G, m.K, m.K0), row)
        assert (m.d, m.K3, m.K4) == (5.85e-6, 4.715, 0.0)
        for k in ("phi_c", "phi_j", "a0", "a_inf", "mu_c", "tau_star", "varphi1", "alpha1",
                  "varphi2", "alpha2", "Delta"):
            assert getattr(m, k) == getattr(h, k)
    assert r.get_material("annular_shear").phi0 == 0.505


def test_sets_are_fresh_frozen_and_overridable():
    a = r.get_material("hermes2016")
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.eta0 = 1.0
    b = r.get_material("hermes2016", eta0=0.01, G=1e4)
    assert (b.eta0, b.G, a.eta0, a.G) == (0.01, 1e4, 0.006, None)
    assert r.get_material(b, K0=2.0).K0 == 2.0


@pytest.mark.parametrize("override, name", [
    (dict(phi_c=0.6), "phi_c"), (dict(phi_j=1.2), "phi_j"), (dict(a0=-1), "a0"),
    (dict(a_inf=0.5), "a_inf"), (dict(mu_c=0), "mu_c"), (dict(tau_star=-5), "tau_star"),
    (dict(eta0=float("nan")), "eta0"), (dict(G=-1.0), "G"), (dict(K=0.0), "K"),
    (dict(Delta=1.5), "Delta"), (dict(K4=0.3), "K4"), (dict(varphi1=-1.0), "varphi1"),
    (dict(phi0=0.6), "phi0"), (dict(d=1e-6), "rho_s"), (dict(K0=float("inf")), "K0"),
])
def test_bad_parameters_name_themselves_and_their_range(override, name):
    with pytest.raises(ValueError, match=name) as err:
        r.get_material("hermes2016", **override)
    msg = str(err.value)
    assert ("range" in msg or "must be" in msg) and "\n" not in msg


def test_unknown_material_and_field():
    with pytest.raises(ValueError, match="unknown material 'oobleck'; valid: singh2018_a"):
        r.get_material("oobleck")
    with pytest.raises(ValueError, match="unknown material parameter"):
        r.get_material("hermes2016", viscosity=1.0)
    with pytest.raises(ValueError, match="G .* is not set for material hermes2016"):
        r.get_material("hermes2016").require("G")


def test_scene_material_puts_a_steady_fit_on_a_scene():
    """The user's steady parameters with the scene's moduli, densities, d and K0 (Tables 4-7)."""
    from rheology.materials import SCENE_FIELDS, scene_material

    fit = r.get_material("hermes2016", phi_j=0.54, eta0=2e-3)
    m = scene_material("annular_shear", fit)
    scene = r.get_material("annular_shear")
    assert (m.phi_j, m.eta0, m.tau_star) == (0.54, 2e-3, fit.tau_star)
    assert all(getattr(m, k) == getattr(scene, k) for k in SCENE_FIELDS)
    own = scene_material("annular_shear", fit.replace(G=1e6, d=1e-5, rho_s=1500.0))
    assert own.G == 1e6 and own.d == 1e-5 and own.rho_s == 1500.0 and own.K == scene.K
    assert scene_material("annular_shear") == scene
    with pytest.raises(ValueError, match="normalised"):
        scene_material("annular_shear", "singh2018_a")


def test_scene_material_phi0_stays_below_the_users_jamming_fraction():
    """A fit jamming below the scene's phi0 gets the default-fraction rule's phi0 instead."""
    from rheology.materials import default_fraction
    from rheology.materials import scene_material

    loose = r.get_material("hermes2016", phi_c=0.40, phi_j=0.48)
    m = scene_material("annular_shear", loose)            # Table 4's phi0 = 0.505 >= 0.48
    assert m.phi0 == default_fraction(loose) and m.phi_c < m.phi0 < m.phi_j


@pytest.mark.parametrize("field", ["b", "varphi1", "alpha1", "varphi2", "alpha2", "xi_eps", "d",
                                   "K3", "K0"])
def test_a_negative_field_is_refused_with_its_physical_reason(field):
    """Each field bounded below by 0 names itself, the range and why (Table 8, Eqs. 7, 9)."""
    with pytest.raises(ValueError) as exc:
        r.get_material("hermes2016").replace(**{field: -1.0})
    msg = str(exc.value)
    assert f"{field} = -1 is outside the valid range [0, inf)" in msg
    assert f"{field.rstrip('12')}" in msg.split("(", 1)[1] and ">= 0" in msg


def test_a_set_value_beyond_float_is_echoed_as_typed():
    with pytest.raises(ValueError, match=r"--set eta0 = 1e400: must be finite"):
        check_set_override(*split_set_item("eta0=1e400"))


def _every_bound():
    from rheology.materials import FIELDS
    return [(k, side) for k, p in FIELDS.items() for side, b in (("lo", p.lo), ("hi", p.hi))
            if b is not None]


@pytest.mark.parametrize("field, side", _every_bound())
def test_every_field_bound_states_its_reason(field, side):
    """Before: --set mu_c=-1 -> '(0, inf)' with no reason (the reason named only the material).
    Every bound of every field gives a reason beyond the material's name."""
    from rheology.materials import FIELDS

    m = r.get_material("hermes2016")
    b = getattr(FIELDS[field], side)
    why = b.at({**vars(m)})[2]
    assert why.startswith("material hermes2016; ") and len(why) > len("material hermes2016; ") + 5


@pytest.mark.parametrize("item, words", [
    ("mu_c=-1", "(0, inf) (mu_c > 0: a contact friction"),
    ("phi_c=-1", "(0, 0.535) (phi_c > 0: a jamming fraction is a volume fraction)"),
    ("phi_j=2", "(0.436, 1) (phi_j < 1: grains jam before they fill the whole volume)"),
    ("Delta=2", "[0, 1] (Delta in [0, 1]"),
])
def test_a_set_field_is_refused_with_the_reason_of_the_bound_it_fails(item, words, tmp_path,
                                                                      monkeypatch, capsys):
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["flow-curve", "--set", item]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not any(tmp_path.iterdir())
