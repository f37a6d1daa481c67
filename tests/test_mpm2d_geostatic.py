"""mpm2d.geostatic: beds that start at rest (issue 10, item 3).

A bed put in its geostatic state and left alone for 0.1 s keeps |v| < 1e-3 m/s and its stress
(the load-carrying field: pore pressure of a loose suspension bed, stress of an elastic one)
within 2 % of the initial field (max over points of |change| / max |initial|).
"""

from __future__ import annotations

import numpy as np
import pytest

from mpm2d import (Grid, LinearElastic, NewtonianFluid, ParticleSet, Simulation, Suspension,
                   box)
from mpm2d.geostatic import geostatic
from rheology import get_material

G0 = 9.81
MAT = get_material("rod_impact", K=8.3e5, G=3.8e5, kappa=8.3e5)


def _sim(mode, axi, h=2e-3, nx=6, nz=10, phi=0.47):
    kw = dict(axisymmetric=axi)
    grid = Grid(nx, nz + 2, h, boundaries=dict(xmin="axis" if axi else "slip", xmax="slip",
                                               ymin="noslip", ymax="free"), **kw)
    x, a = box((0.0, 0.0), (nx * h, nz * h), h / 2)
    if mode == "locked":
        sets = [ParticleSet("bed", Suspension(MAT, locked=True), x, a, phi=phi, f=0.3, **kw)]
    elif mode == "elastic":
        sets = [ParticleSet("bed", LinearElastic(1600.0, 8.3e5, 3.8e5), x, a, **kw)]
    else:
        sets = [ParticleSet("grains", Suspension(MAT), x, a, phi=phi, f=0.3, **kw),
                ParticleSet("fluid", NewtonianFluid.from_material(MAT), x, a, phi=phi, **kw)]
    return Simulation(grid, sets, gravity=(0.0, -G0)), sets


def _field(mode, sets):
    if mode == "elastic":
        return sets[0].stress.reshape(len(sets[0]), 9).copy()
    return np.concatenate([sets[-1].pf, sets[0].stress.reshape(-1)])


@pytest.mark.parametrize("mode, axi, phi", [("locked", True, 0.47), ("two-phase", False, 0.47),
                                            ("elastic", True, 0.47), ("locked", False, 0.47),
                                            ("locked", True, 0.56), ("two-phase", False, 0.56)])
def test_bed_left_alone_stays_at_rest(mode, axi, phi):
    """Loose beds (phi = 0.47 < phi_j = 0.535: grains stress-free, f = 0) and jammed ones
    (phi = 0.56: grains carry the buoyant weight with K_lat, f = 1)."""
    sim, sets = _sim(mode, axi, phi=phi)
    info = geostatic(sim)
    s0 = _field(mode, sets)
    x0 = [s.x.copy() for s in sets]
    sim.run(0.1)
    vmax = max(float(np.abs(s.v).max()) for s in sets)
    change = np.abs(_field(mode, sets) - s0).max() / np.abs(s0).max()
    assert vmax < 1e-3, vmax
    assert change < 0.02, change
    assert max(float(np.abs(s.x - x).max()) for s, x in zip(sets, x0)) < 1e-5
    if mode != "elastic":
        jammed = phi >= MAT.phi_j
        f_rest = 1.0 if jammed else 0.0                           # structure at rest
        assert np.all(np.abs(sets[0].f - f_rest) < 1e-9)
        assert info["bed.jammed_fraction" if mode == "locked" else "grains.jammed_fraction"] \
            == (1.0 if jammed else 0.0)
        if jammed:                                                # grains keep their load
            assert np.abs(sets[0].stress).max() > 0.5 * (phi * (MAT.rho_s - MAT.rho_f) * G0
                                                          * 20e-3)


@pytest.mark.parametrize("mode, axi, phi", [("locked", True, 0.47), ("two-phase", False, 0.47),
                                            ("elastic", True, 0.47), ("elastic", False, 0.47),
                                            ("locked", False, 0.56)])
def test_analytic_state_is_the_discrete_rest_state(mode, axi, phi):
    """The stated (analytic) geostatic field is already the engine's discrete equilibrium: the
    damped relaxation, which settles on whatever the discretisation holds at rest, moves it by
    < 0.05 % of its largest value at every point (before the well-balanced body force of
    mpm2d.shape.hydrostatic_coefficient: the top points' pressure by 50 % of their own)."""
    sim, sets = _sim(mode, axi, phi=phi)
    geostatic(sim, relax=False)
    exact = _field(mode, sets)
    sim, sets = _sim(mode, axi, phi=phi)
    info = geostatic(sim)
    assert info["relax_vmax_m_per_s"] < 1e-5
    relaxed = _field(mode, sets)
    assert np.abs(relaxed - exact).max() < 5e-4 * np.abs(exact).max()
    top = sets[-1].x[:, 1] > 20e-3 - 1e-3                        # the top cell row
    val = (-sets[0].stress[:, 1, 1] if mode == "elastic" else sets[-1].pf)[top]
    d = 20e-3 - sets[-1].x[top, 1]
    rho = sets[-1].m[top] / sets[-1].V[top] if mode != "two-phase" else \
        (sets[0].m[top] + sets[1].m[top]) / sets[1].V[top]
    if mode == "locked" and phi >= MAT.phi_j:                    # jammed: grains + rho_f g d
        return
    assert np.allclose(val, rho * G0 * d, rtol=2e-3), val / (rho * G0 * d)


def test_geostatic_state_values():
    """The stated state: loose locked bed p_f = rho_mix g d (grains free); elastic bed
    sigma_zz = -rho g d with the oedometric K_lat = (3K - 2G)/(3K + 4G) (or the given one)."""
    sim, (bed,) = _sim("locked", True)
    geostatic(sim, relax=False)
    d = 20e-3 - bed.x[:, 1]
    rho_mix = bed.m / bed.V
    assert np.allclose(bed.pf, rho_mix * G0 * d, rtol=1e-3)
    assert np.all(bed.stress == 0.0)
    sim, (el,) = _sim("elastic", False)
    geostatic(sim, relax=False, K_lat=0.7)
    d = 20e-3 - el.x[:, 1]
    assert np.allclose(el.stress[:, 1, 1], -1600.0 * G0 * d)
    assert np.allclose(el.stress[:, 0, 0], 0.7 * el.stress[:, 1, 1])
    with pytest.raises(ValueError, match="K_lat"):
        geostatic(_sim("elastic", False)[0], K_lat=3.0)
    sim, _ = _sim("elastic", False)
    sim.gravity[:] = (1.0, -G0)
    with pytest.raises(ValueError, match="gravity"):
        geostatic(sim)


def test_resume_after_geostatic_and_contact_is_bit_for_bit():
    """A rod_drop model (geostatic bed, free rod in contact) continued from a state after k
    steps equals the uninterrupted run, array for array (the relaxation once left shadow
    attributes that a checkpoint load did not replace)."""
    from mpm2d.scenes import rod_drop

    params = dict(radius=0.006, depth=0.006, rod_radius=0.002, rod_length=0.004, t_end=0.002,
                  cells_per_mm=0.5, v0=2.0)
    full = rod_drop.setup(**params).sim
    touched = False
    for _ in range(80):
        full.step()
        touched |= bool(full.bodies[0].force[1] != 0.0)
    part = rod_drop.setup(**params).sim
    for _ in range(30):
        part.step()
    st = {k: np.array(v, copy=True) for k, v in part.state().items()}
    resumed = rod_drop.setup(**params).sim
    resumed.load_state(st)
    for _ in range(50):
        resumed.step()
    a, b = full.state(), resumed.state()
    assert a.keys() == b.keys()
    for k in a:
        assert np.array_equal(a[k], b[k]), k
    assert touched                                                # the rod met the bed


def test_inplace_update_does_not_shadow_the_arrays():
    sim, (bed,) = _sim("elastic", False)
    bed.v *= 2.0
    bed.arrays["v"] = np.ones_like(bed.arrays["v"])
    assert bed.v is bed.arrays["v"] and np.all(bed.v == 1.0)
