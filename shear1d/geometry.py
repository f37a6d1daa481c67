"""Finite-volume grids across the gap of a plane or annular (wide-gap) Couette cell.

The gap is cut into ``n`` equal cells. Material state (granular stress, structure f, volume
fraction phi) lives at cell centres ``centres[j]``; the shear velocity lives on the ``n + 1``
faces ``faces[k]``, the two walls being faces 0 (moving wall: the bob, or the moving plate) and
``n`` (fixed wall). Every metric the kernels need is precomputed here, so the kernels are the same
for both geometries:

- shear rate in cell j: ``gdot_j = cg[j] (v[j+1] w[j+1] - v[j] w[j])``; annular
  ``gdot = r d(v/r)/dr`` (cg = r_j/dr, w = 1/r_face), plane ``gdot = dv/dy`` (cg = 1/dy, w = 1);
- momentum on face k (a dual cell from centre k-1 to centre k; half cells at the walls):
  ``rho M[k] dv_k/dt = A[k] tau_k - A[k-1] tau_{k-1}`` with A = r^2 and ``M = int r^2 dr``
  (angular momentum, exactly conserved) or A = 1, M = dy;
- radial (cross-gap) fluxes for the two-phase mode: ``div_j(F) = (a[j+1] F[j+1] - a[j] F[j])/V[j]``
  with face areas a = r (plane: 1) and cell volumes V = r_j dr (plane: dy), and the hoop factor
  ``1/r`` (plane: 0) for ``v_r/r`` and ``(sigma_rr - sigma_thth)/r``.

All lengths in metres.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from runkit.limits import LENGTH_MAX, LENGTH_MIN, Bound, ge, le
from runkit.params import Param

KINDS = ("plane", "annular")

#: Smallest cell, in grain diameters d: a cell holds averages over grains (phi, f, the granular
#: stress), which mean nothing in a cell narrower than one grain (the defaults' cells are 17-20
#: grains of 5.85 um).
CELL_MIN_GRAINS = 1.0
#: Smallest bob radius, in grain diameters: the bob is a continuum wall only if its curvature
#: radius is many grains.
R_INNER_MIN_GRAINS = 10.0

#: Cells across the gap: at least 4 (a shear profile and a front need cells inside the gap
#: besides the two at the walls), at most 20000 (the explicit method's cost grows as cells^2).
CELLS = Param(ge(4, "fewer cells resolve no shear profile across the gap (a front needs cells "
                    "inside it besides the two at the walls)"),
              le(20000, "the explicit method's cost grows as cells^2: hours at 20000"),
              kind="integer")
#: The bob radius (annular) or the gap (plane) [m]: the physical lengths (runkit.limits).
LENGTH = Param(LENGTH_MIN, LENGTH_MAX, unit="m")
#: The cup radius [m]: beyond the bob, at most the largest length.
R_OUTER = Param(Bound(lambda p: p["inner"], False, lambda p: f"the cup must lie beyond the bob, "
                      f"a radius of {p['inner']:g} m"), LENGTH_MAX, unit="m")


def min_gap(n_cells: int, d: float) -> float:
    """Smallest gap [m] for ``n_cells`` cells of grains of diameter ``d`` [m] (CELL_MIN_GRAINS)."""
    return CELL_MIN_GRAINS * float(d) * int(n_cells)


@dataclass(frozen=True)
class Grid:
    """Uniform finite-volume grid across a Couette gap.

    Parameters
    ----------
    kind : {"plane", "annular"}
        Plane Couette (coordinate y from the moving plate) or annular Couette (radius r; the inner
        cylinder turns, the outer one is at rest).
    inner, outer : float
        Positions of the moving and the fixed wall [m]: the bob radius R_i and the cup radius R_o
        (annular, 0 < R_i < R_o), or 0 and the gap H (plane).
    n : int
        Number of cells, :data:`CELLS`.

    Raises ValueError (:class:`runkit.params.OutOfRange` naming ``n_cells``, ``r_inner``,
    ``r_outer`` or ``gap``) outside :data:`CELLS`, :data:`LENGTH`, :data:`R_OUTER`.
    """

    kind: str
    inner: float
    outer: float
    n: int
    faces: np.ndarray = field(init=False, repr=False, compare=False)
    centres: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        Param(kind="choice", choices=KINDS).check("geometry kind", self.kind)
        object.__setattr__(self, "n", CELLS.check("n_cells", self.n))
        if self.annular:
            LENGTH.check("r_inner", self.inner)
            R_OUTER.check("r_outer", self.outer, dict(inner=self.inner))
        else:
            LENGTH.check("gap", self.outer - self.inner)
        faces = np.linspace(self.inner, self.outer, self.n + 1)
        object.__setattr__(self, "faces", faces)
        object.__setattr__(self, "centres", 0.5 * (faces[1:] + faces[:-1]))

    @property
    def gap(self) -> float:
        """Gap width [m]."""
        return self.outer - self.inner

    @property
    def dx(self) -> float:
        """Cell size [m]."""
        return self.gap / self.n

    @property
    def annular(self) -> bool:
        return self.kind == "annular"

    def shear_metric(self) -> tuple[np.ndarray, np.ndarray]:
        """(cg, w): ``gdot_j = cg[j] (v[j+1] w[j+1] - v[j] w[j])`` [1/m, -]."""
        if self.annular:
            return self.centres / self.dx, 1.0 / self.faces
        return np.full(self.n, 1.0 / self.dx), np.ones(self.n + 1)

    def momentum_metric(self) -> tuple[np.ndarray, np.ndarray, float]:
        """(A, M, A_wall): cell lever factors A[j], face dual volumes M[k] and A at the moving wall.

        ``rho M[k] dv_k/dt = A[k] tau_k - A[k-1] tau_{k-1}`` for interior faces; M[0] is the half
        dual cell at the moving wall (used when that wall is stress-driven), M[n] at the fixed wall.
        """
        c, f = self.centres, self.faces
        pts = np.concatenate([[f[0]], c, [f[-1]]])
        if self.annular:
            return c ** 2, (pts[1:] ** 3 - pts[:-1] ** 3) / 3.0, f[0] ** 2
        return np.ones(self.n), np.diff(pts), 1.0

    def flux_metric(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(a, V, hoop_cell, hoop_face) for cross-gap fluxes (two-phase mode): face areas per
        unit angle and height (r, or 1) [m or -], cell volumes (r dr, or dy), 1/r at cells and
        faces (0 for the plane cell) [1/m]."""
        if self.annular:
            return (self.faces.copy(), self.centres * self.dx, 1.0 / self.centres,
                    1.0 / self.faces)
        return (np.ones(self.n + 1), np.full(self.n, self.dx), np.zeros(self.n),
                np.zeros(self.n + 1))

    def cell_volumes(self) -> np.ndarray:
        """Cell volumes per radian and unit height (annular, r dr) or per unit area (plane) [m^2 or m]."""
        return self.flux_metric()[1]

    def rigid_speed(self, u_wall: float, x: np.ndarray) -> np.ndarray:
        """Speed of rigid motion with the moving wall at positions x [m/s]: omega r or U."""
        x = np.asarray(x, dtype=float)
        return u_wall * x / self.inner if self.annular else np.full_like(x, u_wall)
