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
