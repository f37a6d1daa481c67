"""shear1d against exact Newtonian solutions: observed second order in space."""

import numpy as np

from shear1d.analytic import annular_steady, plane_couette_startup
from shear1d.integrate import solve
from shear1d.scenes import annular_shear_jamming, plane_couette

PHI = 1e-6      # granular stress ~1e-12 of the fluid's: a Newtonian fluid eta0 (1 + 5/2 phi)


def _orders(errors):
    e = np.asarray(errors)
    return np.log2(e[:-1] / e[1:])


def test_plane_couette_startup_is_second_order():
    gap, speed, errors = 1e-2, 1e-2, []
    for n in (8, 16, 32):
        pb = plane_couette(speed, gap=gap, n_cells=n, phi0=PHI)
        nu = pb.material.eta0 * (1 + 2.5 * PHI) / pb.material.rho_f
        t = 0.05 * gap ** 2 / nu
        res = solve(pb, t, n_out=1, rtol=1e-9)
        exact = plane_couette_startup(pb.grid.faces, t, gap, speed, nu)
        errors.append(np.sqrt(np.mean((res.field("v")[-1] - exact) ** 2)) / speed)
    assert np.all(_orders(errors) > 1.9), errors
    assert errors[-1] < 1e-3


def test_annular_steady_profile_is_second_order():
    errors = []
    for n in (8, 16, 32):
        pb, _ = annular_shear_jamming(1e-2, n_cells=n, phi0=PHI)
        g, m = pb.grid, pb.material
        res = solve(pb, 3.0 * g.gap ** 2 * m.rho_f / m.eta0, n_out=1, rtol=1e-9)
        exact = annular_steady(g.faces, g.inner, g.outer, 1e-2)
        errors.append(np.max(np.abs(res.field("v")[-1] - exact)) / 1e-2)
    assert np.all(_orders(errors) > 1.9), errors
    assert errors[-1] < 5e-4


def test_analytic_solutions_satisfy_their_boundary_conditions():
    y = np.array([0.0, 1e-2])
    v = plane_couette_startup(y, 10.0, 1e-2, 0.5, 1e-5)
    assert abs(v[0] - 0.5) < 1e-12 and abs(v[1]) < 1e-12
    r = np.array([0.01, 0.03])
    assert np.allclose(annular_steady(r, 0.01, 0.03, 0.2), [0.2, 0.0], atol=1e-15)
