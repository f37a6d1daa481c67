"""The yield-rules variant (material field ``rules``) is settable in every tier: rheometer and
shear1d ``--set rules=...``, every mpm2d scene with a suspension (``run`` and ``sweep``)."""

import numpy as np
import pandas as pd
import pytest

from rheology.materials import RULES
from mpm2d.scenes import SCENES, get_setup, get_spec

SUSPENSION_SCENES = ("annular", "column", "impact", "intruder", "rod_drop", "shear", "wheel")


def test_every_suspension_scene_declares_the_rules():
    import inspect

    from mpm2d import materials as mm

    for name in SCENES:
        source = inspect.getsource(inspect.getmodule(get_setup(name)))
        uses = "Suspension(" in source or "suspension_bed(" in source
        assert uses == (name in SUSPENSION_SCENES), name
    for name in SUSPENSION_SCENES:
        spec = get_spec(name)
        assert spec.defaults["rules"] == "table8"
        assert spec.params["rules"].options() == RULES
        assert spec.coerce({"rules": "MPM_3D"}) == {"rules": "mpm_3d"}
        with pytest.raises(ValueError, match="^rules = 'x' is not one of table8, mpm_3d$"):
            spec.coerce({"rules": "x"})
    assert mm.Suspension                                 # the law the scenes build


@pytest.mark.parametrize("rules, code", [("table8", 0.0), ("mpm_3d", 1.0)])
def test_the_scene_builds_its_law_with_the_rules(rules, code):
    for name, kw in (("shear", {}), ("annular", dict(cells=4, rows=4))):
        scene = get_setup(name)(rules=rules, **kw)
        law = scene.sim.sets[0].material
        assert law.m.rules == rules and law.P[-1] == code and scene.params["rules"] == rules


def test_a_sweep_over_the_rules_is_two_cases():
    from mpm2d.sweep import case_name, check_distinct_cases, expand, parse_grid

    grid = parse_grid(["rules=table8,mpm_3d", "phi=0.4"])
    cases = expand(grid)
    assert cases == [{"rules": "table8", "phi": "0.4"}, {"rules": "mpm_3d", "phi": "0.4"}]
    check_distinct_cases(grid)
    assert len({case_name(c) for c in cases}) == 2
    spec = get_spec("shear")
    assert [spec.coerce(c)["rules"] for c in cases] == ["table8", "mpm_3d"]


def test_mpm2d_run_refuses_unknown_rules(tmp_path, capsys):
    from mpm2d.cli import main

    assert main(["run", "shear", "--set", "rules=mpm3d", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rules = 'mpm3d' is not one of table8, mpm_3d" in err[0]
    assert not (tmp_path / "o").exists()


def test_rheometer_material_point_under_each_rule(tmp_path):
    """Shear from rest under a contact pressure p0 = 100 Pa: under mpm_3d the loose point
    (phi 0.45 < phi_m) stays elastic while tau = G gdot t <= (mu_1 + K3 (phi - phi_m)) p0
    (0.789 p0: 15.8 ms at G = 1e4 Pa, gdot = 0.5 1/s), then flows; under table8 it flows (and
    compacts) at once. And the material point starts from zero stress (pressure0 = 0)."""
    from rheometer.cli import main

    frames = {}
    for rules in RULES:
        out = tmp_path / f"{rules}.csv"
        assert main(["material-point", "--material", "hermes2016", "--phi", "0.45",
                     "--pressure0", "100", "--rate", "0.5", "--t-end", "0.05", "--dt", "1e-3",
                     "--set", f"rules={rules}", "--out", str(out)]) == 0
        frames[rules] = pd.read_csv(out)
    t8, m3 = frames["table8"].iloc[1:], frames["mpm_3d"].iloc[1:]
    assert (t8["case"] != "elastic").all()
    import rheology

    m = rheology.get_material("hermes2016")
    t_yield = (m.mu_c + m.K3 * (0.45 - m.phi_j)) * 100.0 / (1e4 * 0.5)            # 15.8 ms
    assert (m3["case"][m3["time_s"] < t_yield] == "elastic").all()
    assert (m3["case"][m3["time_s"] > t_yield + 1e-3] != "elastic").all()
    out = tmp_path / "zero.csv"
    assert main(["material-point", "--material", "hermes2016", "--phi", "0.45", "--rate", "5",
                 "--t-end", "0.05", "--pressure0", "0", "--out", str(out)]) == 0
    df = pd.read_csv(out)
    p = df["granular_pressure_Pa"]
    assert p.iloc[0] == 0 and np.all(p.iloc[1:] > 0)
