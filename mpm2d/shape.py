"""Quadratic B-spline shape functions on a uniform grid (numba, inlined into the kernels).

Why quadratic B-splines: they are C1, so a particle crossing a cell edge sees a continuous
gradient (no cell-crossing noise of linear hat functions), they reproduce linear fields exactly
(partition of unity and linear completeness: sum_i N_i = 1, sum_i N_i x_i = x_p), and each particle
touches only 3 x 3 nodes in 2-D. Cubic splines (4 x 4 = 16 nodes) would nearly double the transfer
cost for no gain in the second-order accuracy the explicit step can deliver.

With g = (x - x0)/h the position in cell units, the base node is b = floor(g - 1/2) and the
fractional offset f = g - b lies in [1/2, 3/2). The three weights (nodes b, b+1, b+2) and their
derivatives times h are::

    N = 1/2 (3/2 - f)^2,   3/4 - (f - 1)^2,   1/2 (f - 1/2)^2
    h dN/dx = f - 3/2,     -2 (f - 1),        f - 1/2

For APIC the inertia-like tensor D_p = sum_i N_i (x_i - x_p)(x_i - x_p)^T = h^2/4 I exactly.
"""

from __future__ import annotations

import math

import numba as nb

from rheology.numba_cache import guard

guard(__file__)                          # drop cached kernels if a module they use changed

#: APIC inertia scaling for quadratic B-splines: D_p^-1 = APIC_D_INV / h^2.
APIC_D_INV = 4.0


@nb.njit(cache=True, inline="always")
def weights(g):
    """Base node, offset and the 3 weights and 3 derivatives (times h) at cell coordinate g."""
    b = math.floor(g - 0.5)
    f = g - b
    w0 = 0.5 * (1.5 - f) ** 2
    w1 = 0.75 - (f - 1.0) ** 2
    w2 = 0.5 * (f - 0.5) ** 2
    return int(b), f, w0, w1, w2, f - 1.5, -2.0 * (f - 1.0), f - 0.5


@nb.njit(cache=True)
def stencil(xp, yp, x0, y0, inv_h):
    """The 3 x 3 B-spline stencil of a point at (xp, yp) [m] on a grid with origin (x0, y0) and
    1/h = inv_h: base nodes bx, by (unpadded), offsets fx, fy (cell units) and the weight and
    derivative (times h) triples wx, wy, dx, dy (:func:`weights` along each axis)."""
    bx, fx, wx0, wx1, wx2, dx0, dx1, dx2 = weights((xp - x0) * inv_h)
    by, fy, wy0, wy1, wy2, dy0, dy1, dy2 = weights((yp - y0) * inv_h)
    return bx, by, fx, fy, (wx0, wx1, wx2), (wy0, wy1, wy2), (dx0, dx1, dx2), (dy0, dy1, dy2)


@nb.njit(cache=True, inline="always")
def hydrostatic_coefficient(area, h):
    """Coefficient c of the hydrostatic (well-balanced) body-force term of one point.

    The point adds ``m_p c h^2 d2N_i/dx_k^2 g_k`` (k = x, y) to the nodal force, i.e.
    ``m_p c g_k`` times (1, -2, 1) over its three nodes along k; with a = sqrt(area)/2 the half
    side of its square domain [m], c = a^2 / (2 h^2) = area / (8 h^2) [-].

    Why: the particle quadrature is the midpoint rule on the point domains. For a bed at rest
    under gravity (stress gradient rho g) it misses, per point and node, V_p a^2/2 rho g N_i''
    (a^2/3 from the stress term, a^2/6 from the weight: the midpoint rule's error
    (2a)^3/24 f'' on a domain where the B-spline is one polynomial). In the interior these
    terms cancel (sum_p m_p N_i'' = rho int N_i'' = 0); on a node whose support is cut by a free
    surface they add up to a^2/2 rho g N_i'(y_s) per unit area: the analytic hydrostatic field
    is then not a discrete equilibrium, and the node above the surface (which sees only the top
    points) forces the top point's pressure to rho g h/8 instead of rho g h/4 (2 points per
    cell): -19.5 % in the top cell row, -0.9 % in the second, in every mode. Adding the missing
    term to the body force makes the hydrostatic state an exact discrete equilibrium (a
    well-balanced scheme, in the sense of Greenberg & LeRoux 1996 and Audusse et al. 2004:
    gravity discretised consistently with the pressure gradient) without touching the stress
    divergence; it changes nothing in the bulk of a uniform bed, keeps the total force and
    torque of gravity (sum_i N_i'' = sum_i x_i N_i'' = 0), and is O(h^2) everywhere.

    Odd layouts: with an odd number of points per cell and direction a point sits on every knot
    (cell centre) and the midpoint errors of the knot points cancel those of the others: the
    hydrostatic state is already exact there (checked for 1 and 3 points; tests), so c = 0. The
    layout n = h / sqrt(area) is rounded to the nearest integer (robust to volume changes of
    -36 % to +78 % at n = 2).

    area : in-plane area of the point [m^2] (V_p, or V_p / r_p in axisymmetry); h : cell [m].
    """
    n = int(h / math.sqrt(area) + 0.5)
    if n % 2 == 1 or n == 0:                 # odd layouts (or points larger than a cell)
        return 0.0
    return area / (8.0 * h * h)
