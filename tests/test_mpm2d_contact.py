"""mpm2d contact (mpm2d.contact): touch only when touching, let go, Coulomb friction, weight.

(a) an elastic block dropped on a rigid floor bounces off: no force while apart;
(b) a block resting on a rigid floor carries its weight to 1%;
(c) a block on an inclined plane (gravity tilted) slides at g (sin th - mu cos th) to 1% for
    mu = 0 and 0.2 and sticks when tan th < mu;
(d) onset: a rigid body h/4, h/2, 2h above a bed feels nothing before its surface reaches the
    bed; the detected impact time is within one step of the exact one (first order in h); with
    the classic rule (contact="mass") it meets the bed where the supports overlap, on approach;
plus momentum conservation of a free body against a deformable body on its own field, and
both phases of a two-phase bed meeting a body.
"""

from __future__ import annotations

import numpy as np
import pytest

from mpm2d import (Grid, LinearElastic, NewtonianFluid, ParticleSet, RigidBody, Simulation,
                   Suspension, box)
from rheology import get_material

G0 = 9.81
H = 0.01


def _floor_block(gap=0.0, theta=0.0, mu=0.0, v0=0.0, E=1e5, nu=0.3, rho=1000.0,
                 geostatic=False, floor=(0.0, 0.4)):
    """A 10 x 10 cm elastic block on a rigid floor slab (x in ``floor``, on a grid 0-40 cm),
    gravity tilted by theta."""
    grid = Grid(40, 24, H, boundaries=dict(xmin="free", xmax="free", ymin="free", ymax="free"))
    xf, af = box((floor[0], 0.0), (floor[1], 0.04), H / 2)
    floor = RigidBody("floor", xf, af, density=1000.0, prescribed="all", mu_w=mu)
    y0 = 0.04 + gap
    x, a = box((0.1, y0), (0.2, y0 + 0.1), H / 2)
    stress = None
    if geostatic:        # free lateral faces: sigma_xx = 0, sigma_yy = -rho g_n depth, plane strain
        sy = -rho * G0 * np.cos(theta) * (y0 + 0.1 - x[:, 1])
        stress = np.zeros((len(x), 3, 3))
        stress[:, 1, 1] = sy
        stress[:, 2, 2] = nu * sy
    blk = ParticleSet("block", LinearElastic(rho, E=E, nu=nu), x, a, v=(0.0, -v0), stress=stress)
    sim = Simulation(grid, [blk], [floor], gravity=(G0 * np.sin(theta), -G0 * np.cos(theta)))
    return sim, blk, floor


def test_dropped_block_separates_and_feels_nothing_while_apart():
    sim, blk, floor = _floor_block(gap=0.02, v0=0.5)
    force, gap_before = [], []
    while sim.t < 0.2:
        gap_before.append(blk.x[:, 1].min() - H / 4 - 0.04)      # point faces vs floor top
        sim.step()
        force.append(-floor.force[1])
    force, gap_before = np.array(force), np.array(gap_before)
    apart = gap_before > 1e-12
    assert np.all(force[apart] == 0.0)                            # exactly no force while apart
    on = force != 0.0
    switches = np.nonzero(np.diff(on.astype(int)))[0]
    assert len(switches) >= 3, switches                           # contact, release, contact
    assert not on[switches[1] + 1]                                # it really let go
    assert np.all(force >= 0.0)                                   # never pulls (no tension)
    # it left the floor: the lowest face rose above it again
    assert gap_before[switches[1] + 5:].max() > 1e-4


@pytest.mark.parametrize("span", [(0.0, 0.4), (-0.4, 0.8)])
def test_resting_block_carries_its_weight(span):
    """Also on a floor three times the grid's width: its parts past the padded grid are left
    out of its nodal area (they were written past the array, corrupting memory)."""
    sim, blk, floor = _floor_block(geostatic=True, floor=span)
    W = blk.m.sum() * G0
    F = []
    while sim.t < 0.2:
        sim.step()
        F.append(-floor.force[1])
    F = np.array(F)
    late = F[len(F) // 2:]
    assert abs(late.mean() / W - 1.0) < 0.01, late.mean() / W
    assert np.abs(late / W - 1.0).max() < 0.02


@pytest.mark.parametrize("theta_deg, mu", [(30.0, 0.0), (30.0, 0.2)])
def test_block_slides_down_incline_at_coulomb_rate(theta_deg, mu):
    th = np.radians(theta_deg)
    sim, blk, floor = _floor_block(theta=th, mu=mu, geostatic=True)
    T, V = [], []
    while sim.t < 0.12:
        sim.step()
        T.append(sim.t)
        V.append(np.sum(blk.m * blk.v[:, 0]) / blk.m.sum())
    T, V = np.array(T), np.array(V)
    a = np.polyfit(T[T > 0.03], V[T > 0.03], 1)[0]
    exact = G0 * (np.sin(th) - mu * np.cos(th))
    assert abs(a / exact - 1.0) < 0.01, (a, exact)


def test_block_sticks_when_tan_theta_below_mu():
    """tan 10 deg = 0.176 < mu = 0.2: after the start-up transient (the initial stress has no
    shear, the shear wave slips the base by ~0.8 mm in the first 0.1 s) the base stops: over
    0.15-0.3 s it moves less than 1% of what a frictionless block slides in that time."""
    th = np.radians(10.0)
    sim, blk, floor = _floor_block(theta=th, mu=0.2, geostatic=True)
    bottom = blk.x[:, 1] < 0.04 + H / 2
    while sim.t < 0.15:
        sim.step()
    x0, t0 = blk.x[bottom, 0].mean(), sim.t
    while sim.t < 0.3:
        sim.step()
    slip = blk.x[bottom, 0].mean() - x0
    free_slide = 0.5 * G0 * np.sin(th) * (sim.t ** 2 - t0 ** 2)   # frictionless, same interval
    assert abs(slip) < 0.01 * free_slide, (slip, free_slide)


def _onset(gap, h, v0=0.5, contact="touch"):
    """A free rigid square 4h wide falls at v0 (no gravity) towards an elastic bed; returns the
    time at the start of the first step with a force, the exact impact time and dt."""
    n = 16
    grid = Grid(n, 16, h, boundaries=dict(xmin="slip", xmax="slip", ymin="noslip", ymax="free"))
    x, a = box((0.0, 0.0), (n * h, 6 * h), h / 2)
    bed = ParticleSet("bed", LinearElastic(1000.0, 1e5, 1e5), x, a)
    y0 = 6 * h + gap
    xb, ab = box((6 * h, y0), (10 * h, y0 + 4 * h), h / 2)
    body = RigidBody("body", xb, ab, density=1000.0, velocity=(0.0, -v0), prescribed="none",
                     contact=contact)
    sim = Simulation(grid, [bed], [body])
    while True:
        t_start = sim.t
        sim.step()
        if body.force[1] != 0.0:
            return t_start, gap / v0, sim.last_dt
        assert np.all(bed.v == 0.0)                               # untouched bed
        assert sim.t < 3 * gap / v0 + 1.0, "never touched"


@pytest.mark.parametrize("frac", [0.25, 0.5, 2.0])
def test_no_force_before_the_surfaces_touch(frac):
    h = 0.01
    t_hit, exact, dt = _onset(frac * h, h)
    assert t_hit >= exact * (1 - 1e-12)                           # nothing before touching
    assert t_hit - exact <= dt * (1 + 1e-9)                       # within one step after


@pytest.mark.parametrize("frac", [0.25, 2.0, 3.0, 4.0])
def test_mass_rule_acts_where_the_supports_overlap(frac):
    """contact="mass" (the classic multi-field rule, mpm_3d's): the body meets the bed as soon
    as a node has mass of both, i.e. a node row lies within 1.5 h (the quadratic B-spline's
    reach) of the bed's top points (h/4 below its surface) and of the body's lowest (h/4 above
    its face): the gap is below 2.25 h. Before that, nothing; at rest, nothing."""
    h = 0.01
    t_hit, exact, dt = _onset(frac * h, h, contact="mass")
    reach = max(0.0, (frac - 2.25) * h / 0.5)                     # gap closes to 2.25 h
    assert t_hit >= reach * (1 - 1e-12) and t_hit - reach <= dt * (1 + 1e-9)
    assert t_hit < exact                                          # before the surfaces meet


def test_mass_rule_acts_only_on_approach():
    """A no-slip body leaving a bed from h/4 above it overlaps the bed's field without a force
    (acting, it would pull the bed's surface up with it); the same body approaching pushes."""
    h = 0.01
    for v in (0.5, -0.5):
        grid = Grid(16, 16, h, boundaries=dict(xmin="slip", xmax="slip", ymin="noslip",
                                              ymax="free"))
        x, a = box((0.0, 0.0), (16 * h, 6 * h), h / 2)
        bed = ParticleSet("bed", LinearElastic(1000.0, 1e5, 1e5), x, a)
        xb, ab = box((6 * h, 6.25 * h), (10 * h, 10.25 * h), h / 2)
        body = RigidBody("body", xb, ab, density=1000.0, velocity=(0.0, v), prescribed="all",
                         contact="mass", mu_w=np.inf)
        sim = Simulation(grid, [bed], [body])
        for _ in range(5):
            sim.step()
            assert (body.contact_nodes == 0) == (v > 0)
        assert np.all(bed.v == 0.0) == (v > 0)


def test_impact_time_converges_first_order():
    gap, errs, dts = 0.013, [], []
    for h in (0.004, 0.002, 0.001):
        t_hit, exact, dt = _onset(gap, h)
        errs.append(t_hit - exact)
        dts.append(dt)
    errs, dts = np.array(errs), np.array(dts)
    assert np.all(errs >= 0) and np.all(errs <= dts * (1 + 1e-9)), (errs, dts)
    assert dts[2] < 0.3 * dts[0]                                  # the bound itself halves


def test_free_body_on_deformable_body_field_conserves_momentum():
    """A free rigid ram hits an elastic block on its own field, which hits a second block:
    rigid-deformable and deformable-deformable contact conserve the total momentum."""
    h = 0.05
    grid = Grid(50, 10, h, boundaries=dict(xmin="free", xmax="free", ymin="periodic",
                                          ymax="periodic"))
    x1, a1 = box((1.0, 0.0), (1.4, 0.5), h / 2)
    x2, a2 = box((1.5, 0.0), (1.9, 0.5), h / 2)
    b1 = ParticleSet("b1", LinearElastic(1000.0, 1e5, 1e5), x1, a1)
    b2 = ParticleSet("b2", LinearElastic(1000.0, 1e5, 1e5), x2, a2)
    xr, ar = box((0.6, 0.0), (0.95, 0.5), h / 2)
    ram = RigidBody("ram", xr, ar, density=500.0, velocity=(2.0, 0.0), prescribed="none",
                    mu_w=0.3)
    sim = Simulation(grid, [b1, b2], [ram], contact_sets={"b1": 0.3})
    p0 = sim.momentum()
    for _ in range(300):
        sim.step()
    assert np.abs(sim.momentum() - p0).max() < 1e-12 * abs(p0[0])
    assert b2.v[:, 0].mean() > 0.05                               # momentum reached b2
    assert ram.velocity[0] < 2.0


def test_two_phase_bed_both_phases_meet_a_prescribed_piston():
    """A piston pushes into a two-phase bed: both phases are stopped from entering it (no
    penetration of either phase's points into the piston) and the reaction is compressive."""
    m = get_material("rod_impact", K=8.3e5, G=3.8e5, kappa=8.3e5)
    h = 0.002
    grid = Grid(20, 2, h, origin=(-6 * h, 0.0),
                boundaries=dict(xmin="free", xmax="slip", ymin="periodic", ymax="periodic"))
    x, a = box((0.0, 0.0), (14 * h, 2 * h), h / 2)
    grains = ParticleSet("grains", Suspension(m), x, a, phi=0.55, f=0.0)
    fluid = ParticleSet("fluid", NewtonianFluid.from_material(m), x, a, phi=0.55)
    xb, ab = box((-4 * h, 0.0), (0.0, 2 * h), h / 2)
    piston = RigidBody("piston", xb, ab, density=1000.0, velocity=(0.05, 0.0), prescribed="all")
    sim = Simulation(grid, [grains, fluid], [piston])
    forces = []
    for _ in range(200):
        sim.step()
        forces.append(-piston.force[0])
    face = piston.center[0] + 2 * h
    for s in (grains, fluid):
        assert s.x[:, 0].min() > face - 0.3 * h, s.name           # neither phase entered
        assert s.v[:, 0].max() > 0.01, s.name                     # both phases pushed
    assert np.mean(forces[100:]) > 0.0                            # compressive reaction


@pytest.mark.parametrize("bed_mode", ["elastic", "locked", "two-phase"])
def test_deformable_body_meets_every_kind_of_bed(bed_mode):
    """An elastic block on its own field (contact_sets) moving at 0.5 m/s towards a bed one cell
    below: no force before the faces touch, then the bed (both phases in two-phase mode) is
    pushed, the block does not pass through, and the exchange conserves the momentum of block
    and bed in the direction without walls (x, periodic: stays 0) and sums to the force."""
    h = 0.002
    m = get_material("rod_impact", K=8.3e5, G=3.8e5, kappa=8.3e5)
    grid = Grid(8, 14, h, boundaries=dict(xmin="periodic", xmax="periodic", ymin="noslip",
                                         ymax="free"))
    x, a = box((0.0, 0.0), (8 * h, 6 * h), h / 2)
    if bed_mode == "elastic":
        beds = [ParticleSet("bed", LinearElastic(1300.0, 8.3e5, 3.8e5), x, a)]
    elif bed_mode == "locked":
        beds = [ParticleSet("bed", Suspension(m, locked=True), x, a, phi=0.47, f=0.0)]
    else:
        beds = [ParticleSet("grains", Suspension(m), x, a, phi=0.47, f=0.0),
                ParticleSet("fluid", NewtonianFluid.from_material(m), x, a, phi=0.47)]
    xb, ab = box((2 * h, 7 * h), (6 * h, 11 * h), h / 2)
    blk = ParticleSet("block", LinearElastic(2000.0, 1e6, 1e6), xb, ab, v=(0.0, -0.5))
    sim = Simulation(grid, beds + [blk], contact_sets={"block": 0.0})
    t_touch = h / 0.5
    forces, times = [], []
    pushed = {b.name: 0.0 for b in beds}
    while sim.t < 3 * t_touch:
        t0 = sim.t
        sim.step()
        forces.append(sim.contact_force["block"][1])
        times.append(t0)
        for b in beds:
            pushed[b.name] = min(pushed[b.name], float(b.v[:, 1].min()))
        if t0 < t_touch * (1 - 1e-9) - sim.last_dt:
            assert forces[-1] == 0.0, (t0, forces[-1])
            assert all(np.abs(b.v).max() < 1e-9 for b in beds)     # round-off only
    assert max(forces) > 0.0                                      # the bed pushes the block up
    assert blk.x[:, 1].min() - h / 4 > 6 * h - 0.5 * h            # no pass-through
    for b in beds:
        assert pushed[b.name] < -0.01, (b.name, pushed)           # every phase was pushed
    assert abs(sim.momentum()[0]) < 1e-12


def test_light_body_on_heavy_bed_is_stable_and_conserves_momentum():
    """Implicit in the body mass: a rigid body 1000x lighter than the bed it hits runs at the
    bed's own stable step without blowing up (an explicit penalty or staggered coupling needs
    dt ~ sqrt(M_body/k)); total momentum exact; it ends up moving with the bed's surface."""
    h = 0.01
    grid = Grid(20, 12, h, boundaries=dict(xmin="periodic", xmax="periodic", ymin="free",
                                          ymax="free"))
    x, a = box((0.0, 0.0), (0.2, 0.06), h / 2)
    bed = ParticleSet("bed", LinearElastic(1000.0, 1e5, 1e5), x, a)
    xb, ab = box((0.06, 0.065), (0.14, 0.085), h / 2)
    body = RigidBody("light", xb, ab, density=1.0, velocity=(0.0, -2.0), prescribed="none")
    sim = Simulation(grid, [bed], [body])
    p0 = sim.momentum()
    for _ in range(400):
        sim.step()
        assert abs(body.velocity[1]) < 2.0 + 1e-9                 # never amplified
    assert np.abs(sim.momentum() - p0).max() < 1e-12 * abs(p0[1])
    assert np.all(np.isfinite(bed.v)) and abs(body.velocity[1]) < 0.5


@pytest.mark.parametrize("shape", ["box", "disk"])
def test_rigid_body_slides_frictionless_on_an_elastic_bed(shape):
    """A free rigid box (corners) or disk on an elastic slab, gravity tilted 20 deg, mu_w = 0:
    it accelerates at g sin(theta) to 1% (the contact normals are the faces actually touching:
    with the body's own corner normals the box ploughed the bed at 0.50 g sin(theta))."""
    from mpm2d import disk

    h, th = 0.01, np.radians(20.0)
    grid = Grid(60, 20, h, boundaries=dict(xmin="free", xmax="free", ymin="noslip",
                                          ymax="free"))
    x, a = box((0.0, 0.0), (0.6, 0.04), h / 2)
    slab = ParticleSet("slab", LinearElastic(1000.0, E=1e6, nu=0.3), x, a)
    if shape == "box":
        xb, ab = box((0.1, 0.04), (0.2, 0.08), h / 2)
    else:
        xb, ab = disk((0.15, 0.09), 0.05, h / 4)
    body = RigidBody("b", xb, ab, density=1000.0, prescribed="none", mu_w=0.0)
    sim = Simulation(grid, [slab], [body], gravity=(G0 * np.sin(th), -G0 * np.cos(th)))
    T, V = [], []
    while sim.t < 0.06:
        sim.step()
        T.append(sim.t)
        V.append(body.velocity[0])
    T, V = np.array(T), np.array(V)
    acc = np.polyfit(T[T > 0.02], V[T > 0.02], 1)[0]
    assert abs(acc / (G0 * np.sin(th)) - 1.0) < 0.01, acc
    # little spurious spin (the disk's point faces are axis-aligned, so its normal forces are
    # not exactly central: |omega| R = 3% of V on this soft bed)
    R = 0.05                                                      # disk radius, box half-width
    assert abs(body.omega) * R < 0.05 * abs(V[-1]), (body.omega, V[-1])
