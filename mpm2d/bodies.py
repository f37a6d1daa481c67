"""Rigid bodies coupled to the material through the grid.

A rigid body is a set of body points (positions and in-plane areas) moving rigidly with its
centre X, angle theta, velocity V and angular velocity omega (a single out-of-plane rotation in
plane strain; in axisymmetry only the axial translation V_z exists). Each step:

1. the body points' area is scattered to the grid, and the nodes it covers (sum_p N_ip A_p >=
   h^2/2, i.e. the nodes inside the body to within h/2) are the body nodes;
2. the free degrees of freedom are found by projecting the body's momentum and the momentum of
   the material on the body nodes onto one rigid motion u_i = V + omega e_z x (x_i - X)
   (an implicit, momentum-conserving, perfectly inelastic no-slip contact):

       [M_b + sum m_i] V - omega sum m_i (r_i)_perp = M_b (V^n + dt g) + sum m_i v_i*
       [I_b + sum m_i |r_i|^2] omega + sum m_i r_i x V = I_b omega^n + sum m_i r_i x v_i*

   (prescribed components are held at their values and move to the right side); then every
   phase's velocity at the body nodes is set to u_i. The material's reaction on the body is
   F = -sum m_i (u_i - v_i*)/dt (reported as ``force``).

Why projection rather than a penalty or a two-field contact algorithm: it is implicit in the
body's mass, so a light body on a heavy material does not go unstable (no added-mass limit on
dt), it conserves the total momentum exactly, and it costs one small linear solve per body.
Its limits: contact is no-slip and cannot separate (the material sticks to the body), and the
body surface is resolved to about h/2.

Body kinds: everything prescribed (a rigid intruder at prescribed velocity); everything free (a
falling rod under gravity); omega prescribed and V free (the hub of a wheel: elastic spokes
and rim are ordinary elastic points attached through the grid, so the wheel is driven at a
prescribed angular velocity while it falls, rolls and sinks freely).
"""

from __future__ import annotations

import numpy as np

from rheology.checks import check_positive, check_range

from .grid import M, fold_scalar
from .transfer import scatter_area

DOFS = ("vx", "vy", "omega")


class RigidBody:
    """A rigid body made of body points.

    Parameters
    ----------
    name : str
    x : (N, 2) array
        Body point positions [m] at t = 0.
    area : (N,) array or float
        In-plane area of each point [m^2].
    density : float
        Density [kg/m^3]; mass = density sum A (per unit thickness) or density sum A r (per radian).
    velocity : (2,) array
        Initial (or prescribed) velocity [m/s].
    omega : float
        Initial (or prescribed) angular velocity [1/s], counter-clockwise (plane strain only).
    prescribed : iterable of "vx", "vy", "omega", or "all" or "none"
        Components held at their given values; the others are free.
    axisymmetric : bool
        Only the axial translation vy (= v_z) can be non-zero or free.
    """

    def __init__(self, name, x, area, density, velocity=(0.0, 0.0), omega=0.0,
                 prescribed="all", axisymmetric=False):
        self.name = name
        x = np.asarray(x, dtype=float).reshape(-1, 2)
        if x.shape[0] == 0:
            raise ValueError(f"body {name!r} has no points")
        self.area = check_range(f"{name}: area", np.broadcast_to(np.asarray(area, float),
                                                                 (x.shape[0],)), 0.0, None,
                                lo_closed=False).copy()
        density = float(check_positive(f"{name}: density", density))
        if prescribed == "all":
            prescribed = DOFS
        elif prescribed in ("none", None):
            prescribed = ()
        bad = set(prescribed) - set(DOFS)
        if bad:
            raise ValueError(f"body {name}: prescribed = {sorted(bad)} not in {DOFS}")
        self.free = np.array([d not in prescribed for d in DOFS])
        self.axisymmetric = axisymmetric
        vel = np.asarray(velocity, dtype=float).reshape(2)
        if axisymmetric:
            if vel[0] != 0.0 or omega != 0.0:
                raise ValueError(f"body {name}: an axisymmetric body moves along the axis only "
                                 f"(velocity = {tuple(vel)}, omega = {omega})")
            self.free[0] = self.free[2] = False
            weight = x[:, 0]
        else:
            weight = np.ones(x.shape[0])
        dm = density * self.area * weight
        self.mass = float(dm.sum())
        self.center = (dm[:, None] * x).sum(axis=0) / self.mass
        self.offset = x - self.center
        self.inertia = float(np.sum(dm * np.einsum("ij,ij->i", self.offset, self.offset)))
        self.theta = 0.0
        self.velocity = vel.copy()
        self.omega = float(omega)
        self.force = np.zeros(2)
        self.torque = 0.0
        self.x = x.copy()

    def describe(self) -> str:
        free = [d for d, f in zip(DOFS, self.free) if f]
        fixed = [d for d, f in zip(DOFS, self.free) if not f]
        return (f"rigid body {self.name}: mass {self.mass:.4g} kg, free {free or 'none'}, "
                f"prescribed {fixed or 'none'}")

    # -------------------------------------------------------------- state (checkpoints)
    STATE = ("center", "theta", "velocity", "omega", "force", "torque")

    def state(self) -> dict:
        return {k: np.array(getattr(self, k)) for k in self.STATE}

    def load_state(self, st: dict) -> None:
        for k in self.STATE:
            val = np.array(st[k])
            setattr(self, k, float(val) if val.ndim == 0 else val.copy())
        self._place()

    def _place(self):
        c, s = np.cos(self.theta), np.sin(self.theta)
        R = np.array([[c, -s], [s, c]])
        self.x = self.center + self.offset @ R.T

    # -------------------------------------------------------------- coupling
    def covered_nodes(self, grid, work):
        """Indices (I, J) of the nodes the body covers (area field >= h^2/2)."""
        work[:] = 0.0
        scatter_area(self.x, self.area, grid.geometry(), work)
        fold_scalar(work, grid.kind, grid.nx, grid.ny)
        return np.nonzero(work >= (0.5 - 1e-9) * grid.h ** 2)

    def constrain(self, fields, nodes, node_x, node_y, dt, gravity):
        """Project the body and the material on its nodes onto one rigid motion (see module)."""
        I, J = nodes
        r = np.stack([node_x[I] - self.center[0], node_y[J] - self.center[1]], axis=1)
        m = np.zeros(I.size)
        p = np.zeros((I.size, 2))
        for G, vg in fields:
            mi = G[I, J, M]
            m += mi
            p += mi[:, None] * vg[I, J]
        g = np.asarray(gravity, dtype=float)
        Mb, Ib = self.mass, self.inertia
        sm = m.sum()
        smr = (m[:, None] * r).sum(axis=0)
        A = np.array([[Mb + sm, 0.0, -smr[1]],
                      [0.0, Mb + sm, smr[0]],
                      [-smr[1], smr[0], Ib + np.sum(m * np.einsum("ij,ij->i", r, r))]])
        rhs = np.array([Mb * (self.velocity[0] + dt * g[0]) + p[:, 0].sum(),
                        Mb * (self.velocity[1] + dt * g[1]) + p[:, 1].sum(),
                        Ib * self.omega + np.sum(r[:, 0] * p[:, 1] - r[:, 1] * p[:, 0])])
        q = np.array([self.velocity[0], self.velocity[1], self.omega])
        free = self.free
        if free.any():
            Af = A[np.ix_(free, free)]
            bf = rhs[free] - A[np.ix_(free, ~free)] @ q[~free]
            q[free] = np.linalg.solve(Af, bf)
        u = np.stack([q[0] - q[2] * r[:, 1], q[1] + q[2] * r[:, 0]], axis=1)
        impulse = (m[:, None] * u - p)                 # momentum given to the material
        self.force = -impulse.sum(axis=0) / dt
        self.torque = -float(np.sum(r[:, 0] * impulse[:, 1] - r[:, 1] * impulse[:, 0])) / dt
        for _, vg in fields:
            vg[I, J] = u
        self.velocity = q[:2].copy()
        self.omega = float(q[2])

    def advance(self, dt: float) -> None:
        """Move the body rigidly over dt with its (new) velocity."""
        self.center = self.center + dt * self.velocity
        self.theta += dt * self.omega
        self._place()

    def kinetic_energy(self) -> float:
        return 0.5 * self.mass * float(self.velocity @ self.velocity) + 0.5 * self.inertia * self.omega ** 2

    def momentum(self) -> np.ndarray:
        return self.mass * self.velocity


def fill(inside, lower, upper, spacing):
    """Points on a regular lattice of ``spacing`` [m] inside a region, with their areas.

    ``inside(x, y) -> bool array``; the lattice is cell-centred in the box [lower, upper], so a
    box of cells of size h with spacing h/2 gets 2 x 2 points per cell at the quarter points.
    Returns ``(x (N, 2), area (N,))``.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    nx = int(round((upper[0] - lower[0]) / spacing))
    ny = int(round((upper[1] - lower[1]) / spacing))
    xs = lower[0] + (np.arange(nx) + 0.5) * spacing
    ys = lower[1] + (np.arange(ny) + 0.5) * spacing
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    keep = np.asarray(inside(X, Y), dtype=bool)
    pts = np.stack([X[keep], Y[keep]], axis=1)
    return pts, np.full(pts.shape[0], spacing * spacing)


def box(lower, upper, spacing):
    """Points filling the rectangle [lower, upper] (see :func:`fill`)."""
    return fill(lambda x, y: np.ones_like(x, dtype=bool), lower, upper, spacing)


def disk(center, radius, spacing, lower=None, upper=None):
    """Points filling a disk of ``radius`` [m] about ``center`` (lattice aligned to ``lower``)."""
    c = np.asarray(center, float)
    lower = c - radius if lower is None else lower
    upper = c + radius if upper is None else upper
    return fill(lambda x, y: (x - c[0]) ** 2 + (y - c[1]) ** 2 < radius ** 2, lower, upper,
                spacing)
