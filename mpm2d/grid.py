"""The background grid: geometry, per-phase node fields and the boundary conditions.

Geometry: ``nx x ny`` square cells of size ``h`` [m] with the lower-left corner at ``origin``;
node (i, j) sits at ``origin + (i, j) h``. Quadratic B-splines reach 1.5 cells beyond a particle,
so the node arrays carry ``PAD = 2`` ghost layers on each side: padded index ``I = i + PAD``.
In axisymmetric mode x is the radius r (origin[0] must be 0, the axis) and y is z.

Node fields of one phase (one velocity field), last axis of an ``(NI, NJ, NF)`` array:
``M`` mass [kg] (per radian in axisymmetry), ``MX, MY`` momentum, ``FX, FY`` force without the
pore-pressure part, ``V`` mixture volume and ``VS`` true solid volume of the phase's points (used
for the nodal volume fraction), ``FPX, FPY`` the pore-pressure force (fluid points only).

Boundaries (per side ``xmin, xmax, ymin, ymax``), all exact for the B-spline basis because they are
applied through mirror images across the wall node line (the image of a particle at distance s
behind the wall is a particle at distance s in front of it):

- ``noslip``: odd images of both velocity components about the wall velocity U (v = U on the wall;
  U tangential, e.g. a moving lid);
- ``slip`` (frictionless): odd normal component, even tangential component (v_n = 0 on the wall);
- ``axis``: the symmetry axis r = 0 of an axisymmetric run, a slip wall (v_r = 0, v_r odd in r);
- ``periodic``: both sides of an axis must be periodic; node nx is node 0;
- ``free``: nothing; the ghost layers are ordinary nodes and particles may not leave them.

Folding adds the images' contributions (mass, momentum, force) to the real nodes after the
particle-to-grid transfer; unfolding writes the mirrored velocities into the ghost nodes before
the grid-to-particle transfer. Linear fields near a wall are then reproduced exactly, which keeps
second-order accuracy up to the wall (zeroing the wall-node velocity alone gives first order).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba as nb
import numpy as np

from runkit.params import check_positive
from rheology.numba_cache import guard

PAD = 2
#: node-field indices
M, MX, MY, FX, FY, V, VS, FPX, FPY = range(9)
NF_ONE, NF_TWO = 5, 9
#: boundary kind codes
FREE, NOSLIP, SLIP, PERIODIC = 0, 1, 2, 3
KINDS = {"free": FREE, "noslip": NOSLIP, "slip": SLIP, "frictionless": SLIP, "axis": SLIP,
         "periodic": PERIODIC}
SIDES = ("xmin", "xmax", "ymin", "ymax")

guard(__file__)                          # drop cached kernels if a module they use changed
_jit = nb.njit(cache=True)


@dataclass
class Grid:
    """Uniform background grid with its boundary conditions.

    Parameters
    ----------
    nx, ny : int
        Number of cells in x (r) and y (z).
    h : float
        Cell size [m].
    origin : (float, float)
        Position of node (0, 0) [m]; in axisymmetry origin[0] = 0 (the axis).
    boundaries : dict
        Kind per side (``xmin, xmax, ymin, ymax``): ``noslip``, ``slip``/``frictionless``,
        ``periodic``, ``free``, or ``axis`` (xmin of an axisymmetric grid only). Default: noslip.
    wall_velocity : dict
        Tangential velocity [m/s] of a ``noslip`` wall, e.g. ``{"ymax": (0.1, 0.0)}``.
    axisymmetric : bool
        x is the radius r and y the axial coordinate z.
    wall_swirl : dict
        Azimuthal (out-of-plane) speed u_theta [m/s] of a cylindrical ``noslip`` r-wall of an
        axisymmetric grid, e.g. ``{"xmin": 0.084}`` for a turning bob; used only by a
        ``Simulation(..., swirl=True)`` (see :mod:`mpm2d.transfer`, swirl kernels).

    Annulus: an axisymmetric grid may start off the axis (origin[0] = R_i > 0) when xmin is a
    ``noslip`` or ``slip`` wall, the surface of an inner cylinder (the bob of a Couette cell).
    """

    nx: int
    ny: int
    h: float
    origin: tuple = (0.0, 0.0)
    boundaries: dict = field(default_factory=dict)
    wall_velocity: dict = field(default_factory=dict)
    axisymmetric: bool = False
    wall_swirl: dict = field(default_factory=dict)

    def __post_init__(self):
        for name in ("nx", "ny"):
            n = getattr(self, name)
            if int(n) != n or n < 2:
                raise ValueError(f"{name} = {n} must be an integer >= 2 (number of cells)")
            setattr(self, name, int(n))
        self.h = float(check_positive("h", self.h))
        self.origin = tuple(float(o) for o in self.origin)
        unknown = set(self.boundaries) - set(SIDES)
        if unknown:
            raise ValueError(f"unknown boundary side(s) {sorted(unknown)}; valid: {SIDES}")
        b = {s: str(self.boundaries.get(s, "noslip")).lower() for s in SIDES}
        for s, k in b.items():
            if k not in KINDS:
                raise ValueError(f"boundary {s} = {k!r} is not one of {sorted(KINDS)}")
            if k == "axis" and (s != "xmin" or not self.axisymmetric):
                raise ValueError(f"boundary {s} = 'axis' is only valid for xmin of an "
                                 "axisymmetric grid")
        for a, c in (("xmin", "xmax"), ("ymin", "ymax")):
            if (b[a] == "periodic") != (b[c] == "periodic"):
                raise ValueError(f"periodic boundaries come in pairs: {a} = {b[a]}, {c} = {b[c]}")
        if self.axisymmetric:
            if self.origin[0] < 0.0:
                raise ValueError(f"origin[0] = {self.origin[0]} must be 0 (the axis r = 0) or, "
                                 "for an annulus, > 0 for an axisymmetric grid")
            if self.origin[0] > 0.0:
                if b["xmin"] not in ("noslip", "slip", "frictionless"):
                    raise ValueError(f"boundary xmin = {b['xmin']!r}: an annular axisymmetric "
                                     f"grid (origin[0] = {self.origin[0]} > 0) needs an inner "
                                     "wall, noslip or slip")
            else:
                if b["xmin"] not in ("axis", "slip", "frictionless"):
                    raise ValueError(f"boundary xmin = {b['xmin']!r} must be 'axis' for an "
                                     "axisymmetric grid (r = 0 is the symmetry axis)")
                b["xmin"] = "axis"
        self.boundaries = b
        self.kind = np.array([KINDS[b[s]] for s in SIDES], dtype=np.int64)
        self.wall_u = np.zeros((4, 2))
        for s, u in self.wall_velocity.items():
            if s not in SIDES:
                raise ValueError(f"unknown wall side {s!r}; valid: {SIDES}")
            if b[s] != "noslip":
                raise ValueError(f"wall_velocity[{s}] needs a noslip wall, {s} is {b[s]}")
            u = np.asarray(u, dtype=float).reshape(2)
            normal = 0 if s.startswith("x") else 1
            if u[normal] != 0.0:
                raise ValueError(f"wall_velocity[{s}] = {tuple(u)} must be tangential (the walls "
                                 "do not move)")
            self.wall_u[SIDES.index(s)] = u
        self.swirl_u = np.zeros(4)
        for s, u in self.wall_swirl.items():
            if s not in ("xmin", "xmax"):
                raise ValueError(f"wall_swirl side {s!r} must be xmin or xmax (a cylindrical "
                                 "wall r = const)")
            if not self.axisymmetric:
                raise ValueError("wall_swirl needs an axisymmetric grid")
            if b[s] != "noslip":
                raise ValueError(f"wall_swirl[{s}] needs a noslip wall, {s} is {b[s]}")
            u = float(u)
            if not np.isfinite(u):
                raise ValueError(f"wall_swirl[{s}] = {u} must be finite [m/s]")
            self.swirl_u[SIDES.index(s)] = u
        self.shape = (self.nx + 1 + 2 * PAD, self.ny + 1 + 2 * PAD)

    # ------------------------------------------------------------------ geometry
    @property
    def lower(self) -> np.ndarray:
        return np.array(self.origin)

    @property
    def upper(self) -> np.ndarray:
        return np.array(self.origin) + self.h * np.array([self.nx, self.ny])

    @property
    def on_axis(self) -> bool:
        """Whether xmin is the symmetry axis r = 0 (axisymmetric grid starting at the axis)."""
        return self.axisymmetric and self.origin[0] == 0.0

    @property
    def periodic(self) -> tuple[bool, bool]:
        return bool(self.kind[0] == PERIODIC), bool(self.kind[2] == PERIODIC)

    def node_positions(self) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates [m] of the padded node columns and rows."""
        i = np.arange(self.shape[0]) - PAD
        j = np.arange(self.shape[1]) - PAD
        return self.origin[0] + i * self.h, self.origin[1] + j * self.h

    def geometry(self) -> np.ndarray:
        """Numeric grid description for the kernels: (x0, y0, h, x1, y1)."""
        lo, hi = self.lower, self.upper
        return np.array([lo[0], lo[1], self.h, hi[0], hi[1]])

    def describe(self) -> str:
        kind = "axisymmetric (r, z)" if self.axisymmetric else "plane strain (x, y)"
        sides = ", ".join(f"{s} {k}" for s, k in self.boundaries.items())
        swirl = "".join(f"; {k} turns at u_theta = {self.swirl_u[SIDES.index(k)]:g} m/s"
                        for k in ("xmin", "xmax") if self.swirl_u[SIDES.index(k)] != 0.0)
        return (f"{kind} grid {self.nx} x {self.ny} cells, h = {self.h:g} m"
                + (f", r from {self.origin[0]:g} m (annulus)" if self.axisymmetric
                   and self.origin[0] > 0 else "") + f"; boundaries: {sides}{swirl}")


# ---------------------------------------------------------------------- fold / unfold kernels
@_jit
def _mirror_sign(kind, comp, normal):
    """Image sign of vector component ``comp`` across a wall whose normal is axis ``normal``."""
    if kind == NOSLIP or comp == normal:
        return -1.0
    return 1.0


@_jit
def _fold_node(G, si, sj, di, dj, kind, normal, ux, uy):
    """Add the image of node (si, sj) into node (di, dj); the source may be the target.

    Periodic: a plain copy. Walls: mass and volumes even, vectors mirrored, momentum mirrored
    about the wall velocity (image momentum = S p + (1 - S) m U, S = -1 or +1 per component).
    """
    nf = G.shape[2]
    if kind == PERIODIC:
        for k in range(nf):
            G[di, dj, k] += G[si, sj, k]
        return
    sx = _mirror_sign(kind, 0, normal)
    sy = _mirror_sign(kind, 1, normal)
    m = G[si, sj, M]
    G[di, dj, M] += m
    G[di, dj, MX] += sx * G[si, sj, MX] + (1.0 - sx) * m * ux
    G[di, dj, MY] += sy * G[si, sj, MY] + (1.0 - sy) * m * uy
    G[di, dj, FX] += sx * G[si, sj, FX]
    G[di, dj, FY] += sy * G[si, sj, FY]
    if nf > V:
        G[di, dj, V] += G[si, sj, V]
        G[di, dj, VS] += G[si, sj, VS]
        G[di, dj, FPX] += sx * G[si, sj, FPX]
        G[di, dj, FPY] += sy * G[si, sj, FPY]


@_jit
def _fold_line(G, axis, t, src, dst, kind, ux, uy, clear):
    if axis == 0:
        _fold_node(G, src, t, dst, t, kind, 0, ux, uy)
        if clear:
            G[src, t, :] = 0.0
    else:
        _fold_node(G, t, src, t, dst, kind, 1, ux, uy)
        if clear:
            G[t, src, :] = 0.0


@_jit
def _fold_pairs(kd, side, n, wall):
    """(source, destination) node indices along one axis folded across one side (not FREE):
    periodic copies (i = -g -> n - g for g = 1..PAD, i = n + g -> g for g = 0..PAD), or mirror
    images about the wall node w (w - d g -> w + d g, d into the domain), with ``wall`` the
    wall node onto itself first."""
    if kd == PERIODIC:
        pairs = [(PAD - g, PAD + n - g) for g in range(1, PAD + 1)]
        pairs += [(PAD + n + g, PAD + g) for g in range(0, PAD + 1)]
        return pairs
    w = PAD if side == 0 else PAD + n
    d = 1 if side == 0 else -1
    pairs = [(w - d * g, w + d * g) for g in range(0 if wall else 1, PAD + 1)]
    return pairs


@_jit
def _unfold_pairs(kd, side, n):
    """(source, destination, on the wall) node indices along one axis that fill one side's
    ghosts (not FREE): periodic copies (g = -PAD..PAD), or mirror images w + d g -> w - d g
    (g = 0..PAD, the wall node onto itself at g = 0)."""
    w = PAD if side == 0 else PAD + n
    d = 1 if side == 0 else -1
    out = []
    for g in range(-PAD, PAD + 1):
        if kd == PERIODIC:
            if g < 0:
                out.append((PAD + n + g, PAD + g, False))
            else:
                out.append((PAD + g, PAD + n + g, False))
        elif g >= 0:
            out.append((w + d * g, w - d * g, g == 0))
    return out


@_jit
def fold(G, kind, wall_u, nx, ny):
    """Add the ghost nodes' contributions (mirror images or periodic copies) into real nodes.

    ``G``: one phase's node fields (NI, NJ, NF); ``kind``/``wall_u``: per side in the order
    xmin, xmax, ymin, ymax. x sides first, then y sides (corners compose).
    """
    for axis in range(2):
        n = nx if axis == 0 else ny
        other = G.shape[1] if axis == 0 else G.shape[0]
        for side in range(2):
            s = 2 * axis + side
            kd = kind[s]
            if kd == FREE or (kd == PERIODIC and side == 1):
                continue
            ux, uy = wall_u[s, 0], wall_u[s, 1]
            pairs = _fold_pairs(kd, side, n, True)
            for t in range(other):
                for src, dst in pairs:
                    _fold_line(G, axis, t, src, dst, kd, ux, uy, src != dst)


@_jit
def unfold(Vg, kind, wall_u, nx, ny, vector):
    """Fill ghost nodes from their images; enforce the wall-node constraint.

    ``Vg`` is (NI, NJ, nc). If ``vector`` (nc = 2) the values mirror like velocities: the wall
    node is projected onto its constraint (v = U for noslip, v_n = 0 for slip) and the ghosts
    get the odd/even images about it. Scalars are copied evenly. y sides first, then x sides.
    """
    NI, NJ, nc = Vg.shape
    for axis in (1, 0):
        n = nx if axis == 0 else ny
        other = NJ if axis == 0 else NI
        for side in range(2):
            s = 2 * axis + side
            kd = kind[s]
            if kd == FREE or (kd == PERIODIC and side == 1):
                continue
            pairs = _unfold_pairs(kd, side, n)
            for t in range(other):
                for src, dst, at_wall in pairs:
                    for c in range(nc):
                        val = Vg[src, t, c] if axis == 0 else Vg[t, src, c]
                        if vector and kd != PERIODIC:
                            sg = _mirror_sign(kd, c, axis)
                            img = sg * val + (1.0 - sg) * wall_u[s, c]
                            val = 0.5 * (val + img) if at_wall else img
                        if axis == 0:
                            Vg[dst, t, c] = val
                        else:
                            Vg[t, dst, c] = val




# ---------------------------------------------------------------------- swirl (angular momentum)
@_jit
def _swirl_sign(kind, side, on_axis):
    """Image sign of the angular momentum l = r v_theta across side ``side`` (0..3).

    noslip walls and the axis: odd about the wall value (v_theta = wall speed; l = 0 on the
    axis); slip walls: even (no shear traction sigma_r_theta / sigma_theta_z on the wall)."""
    kd = kind[side]
    if kd == NOSLIP or (side == 0 and on_axis):
        return -1.0
    return 1.0


@_jit
def fold_swirl(W, m, kind, lw, nx, ny, on_axis):
    """Fold the swirl node fields W (NI, NJ, 2) = (sum N m l, torque) like :func:`fold`.

    ``m`` is the unfolded nodal mass (NI, NJ) (the image angular momentum about a wall with
    l_w = R u_theta is S (m l) + (1 - S) m l_w); ``lw`` (4,) the wall values of l per side
    (0 on z-walls: they do not turn). Must run before the main fold of the mass.
    """
    for axis in range(2):
        n = nx if axis == 0 else ny
        other = W.shape[1] if axis == 0 else W.shape[0]
        for side in range(2):
            sd = 2 * axis + side
            kd = kind[sd]
            if kd == FREE or (kd == PERIODIC and side == 1):
                continue
            S = _swirl_sign(kind, sd, on_axis)
            pairs = _fold_pairs(kd, side, n, True)
            for t in range(other):
                for src, dst in pairs:
                    si, sj = (src, t) if axis == 0 else (t, src)
                    di, dj = (dst, t) if axis == 0 else (t, dst)
                    if kd == PERIODIC:
                        W[di, dj, 0] += W[si, sj, 0]
                        W[di, dj, 1] += W[si, sj, 1]
                        W[si, sj, 0] = W[si, sj, 1] = 0.0
                        m[di, dj] += m[si, sj]
                        m[si, sj] = 0.0
                    else:
                        ms = m[si, sj]
                        W[di, dj, 0] += S * W[si, sj, 0] + (1.0 - S) * ms * lw[sd]
                        W[di, dj, 1] += S * W[si, sj, 1]
                        m[di, dj] += ms
                        if src != dst:
                            W[si, sj, 0] = W[si, sj, 1] = 0.0
                            m[si, sj] = 0.0


@_jit
def unfold_swirl(lg, kind, lw, nx, ny, on_axis):
    """Ghost nodes of the nodal angular momentum per unit mass lg (NI, NJ): the wall node takes
    its constraint (l = l_w on noslip walls and the axis), ghosts the odd/even images."""
    NI, NJ = lg.shape
    for axis in (1, 0):
        n = nx if axis == 0 else ny
        other = NJ if axis == 0 else NI
        for side in range(2):
            sd = 2 * axis + side
            kd = kind[sd]
            if kd == FREE or (kd == PERIODIC and side == 1):
                continue
            S = _swirl_sign(kind, sd, on_axis)
            pairs = _unfold_pairs(kd, side, n)
            for t in range(other):
                for src, dst, at_wall in pairs:
                    val = lg[src, t] if axis == 0 else lg[t, src]
                    if kd != PERIODIC:
                        img = S * val + (1.0 - S) * lw[sd]
                        val = 0.5 * (val + img) if at_wall else img
                    if axis == 0:
                        lg[dst, t] = val
                    else:
                        lg[t, dst] = val
