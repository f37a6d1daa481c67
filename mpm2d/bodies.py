"""Rigid bodies coupled to the material through the grid.

A rigid body is a set of body points (positions and in-plane areas) moving rigidly with its
centre X, angle theta, velocity V and angular velocity omega (a single out-of-plane rotation in
plane strain; in axisymmetry only the axial translation V_z exists). Each step the body meets
every particle field through :mod:`mpm2d.contact`: contact only where the body's surface touches
the material's (``contact="touch"``: gap criterion from the points' extents; ``"mass"``: wherever
both have nodal mass, Bardenhagen et al. 2000), only while they approach along the normal, with
Coulomb friction ``mu_w`` (0 frictionless, ``inf`` no-slip) and free separation (no tension).
Fields listed in ``bonded_to`` (e.g. the elastic spokes of a wheel on its rigid hub) are glued
instead: every node the body covers (sum_p N_ip A_p >= h^2/2) moves rigidly with it. The
body's velocity and the contact impulses are solved together, implicitly in the body
mass (no added-mass limit on dt), and momentum is exchanged exactly:

    M q^{n+1} = M (q^n + dt g) - sum_k J_k^T lambda_k,   F = -sum_k lambda_k / dt

(prescribed components are held; their reaction is reported as ``force``/``torque``).

Body kinds: everything prescribed (a rigid intruder, a floor, an inclined plane); everything free
(a falling rod under gravity); omega prescribed and V free (the hub of a wheel: elastic spokes and
rim are ordinary elastic points bonded to it, so the wheel is driven at a prescribed angular
velocity while it falls, rolls and sinks freely).
"""

from __future__ import annotations

import numpy as np

from runkit.params import OutOfRange, check_positive, check_range, shown


DOFS = ("vx", "vy", "omega")
#: where a body meets a field (mpm2d.contact): its surface touching the field's points, or any
#: node where both have mass
CONTACT_RULES = ("touch", "mass")


def check_mu(name, mu) -> float:
    """A Coulomb coefficient: a number in [0, inf] (inf = no slip); ValueError otherwise."""
    try:
        mu = float(mu)
    except (TypeError, ValueError):
        raise ValueError(f"{name} = {mu!r} is not a number") from None
    if not (mu >= 0.0):
        raise OutOfRange(name, shown(mu), "[0, inf]", "inf = no slip")
    return mu


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
    mu_w : float
        Coulomb friction coefficient of the contact with the material [-], 0 (frictionless,
        default) to ``inf`` (no slip).
    bonded_to : iterable of str
        Names of particle sets glued to the body (their field moves rigidly with it on every node
        the body covers), e.g. the spokes of a wheel on its hub.
    contact : {"touch", "mass"}
        Where the body meets a field (:mod:`mpm2d.contact`): ``touch`` (default) at the nodes
        covered by field points whose squares touch the body's, normal from those contacts;
        ``mass`` at every node where both have mass, normal from the body's mass gradient (the
        classic multi-field rule, which acts up to the shape functions' reach before the
        surfaces meet).

    Raises
    ------
    ValueError
        No points, a non-positive area or density, an unknown prescribed component or contact
        rule, mu_w not in [0, inf], or in-plane motion of an axisymmetric body.
    """

    def __init__(self, name, x, area, density, velocity=(0.0, 0.0), omega=0.0,
                 prescribed="all", axisymmetric=False, mu_w=0.0, bonded_to=(),
                 contact="touch"):
        self.name = name
        self.mu_w = check_mu(f"{name}: mu_w", mu_w)
        if contact not in CONTACT_RULES:
            raise ValueError(f"body {name}: contact = {contact!r} must be one of {CONTACT_RULES}")
        self.contact = contact
        self.bonded_to = tuple(bonded_to)
        self.contact_nodes = 0
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

    def describe(self, extent: str = "") -> str:
        """One line: mass (``extent``: e.g. " per radian" in axisymmetry), free and prescribed
        degrees of freedom, contact."""
        free = [d for d, f in zip(DOFS, self.free) if f]
        fixed = [d for d, f in zip(DOFS, self.free) if not f]
        return (f"rigid body {self.name}: mass {self.mass:.4g} kg{extent}, free {free or 'none'}, "
                f"prescribed {fixed or 'none'}; contact {self.contact}, mu_w = {self.mu_w:g}"
                + (f", bonded to {list(self.bonded_to)}" if self.bonded_to else ""))

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
    @property
    def side(self) -> np.ndarray:
        """Side sqrt(A) of each body point [m] (its extent for the contact gap)."""
        return np.sqrt(self.area)

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
