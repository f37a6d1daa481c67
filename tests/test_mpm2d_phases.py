"""mpm2d two-phase coupling, the suspension law in the MPM, and Newtonian flow."""

from __future__ import annotations

import numpy as np
import pytest

from mpm2d import (Drag, Grid, LinearElastic, NewtonianFluid, ParticleSet, Simulation,
                   Suspension, box)
from mpm2d.analytic import observed_orders
from mpm2d.run import run_scene
from mpm2d.scenes import column, couette, shear, terzaghi
from rheology import get_material


def _run(setup, path, **params):
    return run_scene(setup, path, params, progress=False, vtk=False, log=lambda m: None)


def test_two_phase_exchange_conserves_momentum_and_mass():
    """Grains and fluid with opposite velocities in a closed periodic box relax to a common
    velocity through the implicit drag (no gravity): total momentum exact, relative velocity
    decays monotonically, masses constant."""
    n, h = 4, 0.01
    grid = Grid(n, n, h, boundaries=dict(xmin="periodic", xmax="periodic", ymin="periodic",
                                        ymax="periodic"))
    x, a = box((0, 0), (n * h, n * h), h / 2)
    grains = ParticleSet("g", LinearElastic(2500.0, 1e5, 1e5), x, a, phi=0.4, v=(0.01, 0.0))
    fluid = ParticleSet("f", NewtonianFluid(1e-3, 1000.0, 1e5), x, a, phi=0.4, v=(-0.02, 0.0))
    sim = Simulation(grid, [grains, fluid], drag=Drag(1e-3, 1e-3, 1000.0))
    assert sim.mode == "two-phase"
    p0, m0 = sim.momentum(), grains.m.sum() + fluid.m.sum()
    rel = []
    for _ in range(50):
        sim.step()
        rel.append(grains.v[:, 0].mean() - fluid.v[:, 0].mean())
    assert np.abs(sim.momentum() - p0).max() < 1e-14 * m0
    assert np.all(np.diff(rel) < 0) and rel[-1] < 0.1 * rel[0]
    assert grains.m.sum() + fluid.m.sum() == m0


def test_terzaghi_consolidation_matches_series(tmp_path):
    res = _run(terzaghi.setup, tmp_path / "tz", cells=16, t_end_T=0.2)
    table = (tmp_path / "tz" / "terzaghi_result.csv").read_text()
    import pandas as pd

    df = pd.read_csv(tmp_path / "tz" / "terzaghi_result.csv")
    assert len(df) == 2, table                                     # T = 0.1 and 0.2
    assert df["max_error"].max() < 0.02                             # of p0
    assert df["settlement_error"].iloc[0] < 0.04
    assert res["manifest"]["mode"] == "two-phase"


def test_settling_column_interface_speed(tmp_path):
    """Kynch: the suspended grains (phi = phi0) settle at the hindered settling speed
    n^2 phi (rho_s - rho_f) g / C(phi, Re) of a closed column."""
    res = _run(column.setup, tmp_path / "col", cells=10, width_cells=2, t_end=0.3)
    import pandas as pd

    r = pd.read_csv(tmp_path / "col" / "column_result.csv").iloc[0]
    assert r["grain_speed_error"] < 0.01, r
    h = res["history"]
    assert h["max_phi"].iloc[-1] > 0.5                              # a bed forms at the bottom


def test_homogeneous_shear_box_follows_one_material_point(tmp_path):
    """Locked mixture in homogeneous shear: the box average equals the single point driven by
    the same L and steps (rheology.local_update), to round-off; the box stays homogeneous."""
    res = _run(shear.setup, tmp_path / "sh", t_end=0.03, rate=50.0)
    import pandas as pd

    r = pd.read_csv(tmp_path / "sh" / "shear_result.csv").iloc[0]
    for col in ("granular_shear_stress_Pa_rel_diff", "granular_pressure_Pa_rel_diff",
                "f_rel_diff"):
        assert r[col] < 1e-10, r
    h = res["history"]
    assert h["f"].iloc[-1] > 0.05                                   # structure builds up
    assert h["spread_shear_stress_Pa"].max() < 1e-9 * h["granular_shear_stress_Pa"].abs().max()


def test_suspension_failure_is_reported_not_silent():
    m = get_material("annular_shear")
    grid = Grid(2, 2, 0.01, boundaries=dict(xmin="periodic", xmax="periodic",
                                            ymin="periodic", ymax="periodic"))
    x, a = box((0, 0), (0.02, 0.02), 0.005)
    with pytest.raises(ValueError, match="phi"):
        ParticleSet("s", Suspension(m), x, a, phi=1.2)
    with pytest.raises(ValueError, match="give phi"):
        ParticleSet("s", Suspension(m), x, a)
    with pytest.raises(ValueError, match="is not set for material hermes2016"):
        Suspension(get_material("hermes2016"))                      # no moduli: refused


def test_couette_startup_converges(tmp_path):
    """Newtonian plane Couette startup against the series: observed order > 1.9."""
    errs = []
    for n in (8, 16):
        _run(couette.setup, tmp_path / f"c{n}", cells=n, t_end_T=0.1)
        import pandas as pd

        df = pd.read_csv(tmp_path / f"c{n}" / "couette_result.csv")
        errs.append(df["max_error"].to_numpy())
    orders = observed_orders([1 / 8, 1 / 16], [errs[0], errs[1]])
    assert np.all(orders > 1.9), orders
    assert errs[1].max() < 0.05
