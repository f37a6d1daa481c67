"""Every tier's ``--set NAME=VALUE`` meets the same physical limits of a material field
(rheology.materials.FIELD_LIMITS): a value no suspension has is refused with the limit's reason
(exit 2, nothing written), a value inside runs."""

import pytest

from rheology.materials import FIELD_LIMITS, check_set_override
from rheometer.cli import main as rheometer_main
from shear1d.cli import main as shear1d_main

TINY = {"G": 1e-300, "K": 1e-300, "kappa": 1e-300, "eta0": 1e-300, "tau_star": 1e-300,
        "rho_s": 1e-300, "rho_f": 1e-300, "d": 1e-155}


@pytest.mark.parametrize("name", sorted(FIELD_LIMITS))
def test_each_limited_field_is_refused_below_its_limit_with_the_reason(name):
    lo, hi = FIELD_LIMITS[name]
    with pytest.raises(ValueError, match=rf"--set {name} = .* is outside the valid range .*\("):
        check_set_override(name, str(TINY[name]))
    with pytest.raises(ValueError, match=rf"--set {name} = "):
        check_set_override(name, str(hi.value * 10))
    assert check_set_override(name, str(lo.value)) == (name, lo.value)   # the bound is closed


@pytest.mark.parametrize("main, argv", [
    (rheometer_main, ["flow-curve"]),
    (rheometer_main, ["startup"]),
    (shear1d_main, ["annular"]),
])
@pytest.mark.parametrize("item", ["G=1e-300", "d=1e-155"])
def test_every_command_refuses_them_before_anything_runs(main, argv, item, tmp_path, capsys):
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as exc:
        main([*argv, "--set", item, "--out", str(out)])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--set {item.split('=')[0]} = " in err[0]
    assert not out.exists() and not list(tmp_path.iterdir())


def test_d_zero_means_no_grain_size_and_stays_valid():
    assert check_set_override("d", "0") == ("d", 0.0)


def test_a_material_file_meets_the_same_limits(tmp_path, capsys):
    """A material file is checked like --set: G = 1e-300 Pa in a file is refused naming the file
    and the field (the Material alone asks only G > 0); a file at the limits is read."""
    import json

    from rheology.materials import load_material, save_material

    ok = tmp_path / "ok.json"
    save_material(ok, __import__("rheology").get_material("hermes2016", G=1.0, d=0.0))
    assert load_material(ok).G == 1.0
    doc = json.loads(ok.read_text())
    (doc["material"] if "material" in doc else doc)["G"] = 1e-300
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"material file bad\.json: G = 1e-300 is outside the "
                                         r"valid range \[1, 1e\+12\] Pa \("):
        load_material(bad)
    out = tmp_path / "run.csv"
    try:
        code = rheometer_main(["startup", "--material", str(bad), "--out", str(out)])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "G = 1e-300" in err[0] and not out.exists()
