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
