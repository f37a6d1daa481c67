"""Brent's method (zeroin) for numba kernels.

The residual is a jitted function passed in, ``res(x, *args)``, with its parameters as a tuple
(numba specialises the solver on both, so the call costs what a direct call costs). Source:
R. P. Brent, Algorithms for Minimization without Derivatives (1973), ch. 4: inverse quadratic
interpolation or the secant step where it stays inside the bracket and shrinks it fast enough,
bisection otherwise; the bracket [b, c] always holds a sign change.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, error_model="numpy", inline="always")
def brent(res, args, xa, xb, fa, fb, rtol, atol, ftol, maxit):
    """Root of ``res(x, *args)`` between xa and xb, fa = res(xa) and fb = res(xb) of opposite
    signs.

    Stops when the bracket is below ``rtol |x| + atol``, or |res| <= ``ftol`` (0: only an exact
    zero). Non-finite end values are bisected, never interpolated. Returns (x, res(x),
    evaluations); evaluations = -1 if ``maxit`` evaluations did not converge (x is then the last
    iterate).
    """
    xc, fc = xa, fa
    d = e = xb - xa
    for it in range(maxit):
        if (fb > 0.0) == (fc > 0.0):
            xc, fc = xa, fa
            d = e = xb - xa
        if abs(fc) < abs(fb):
            xa, xb, xc = xb, xc, xb
            fa, fb, fc = fb, fc, fb
        tol = rtol * abs(xb) + atol
        xm = 0.5 * (xc - xb)
        if abs(xm) <= tol or fb == 0.0 or abs(fb) <= ftol:
            return xb, fb, it
        if abs(e) >= tol and abs(fa) > abs(fb) and np.isfinite(fa) and np.isfinite(fc):
            s = fb / fa
            if xa == xc:
                pp = 2.0 * xm * s
                q = 1.0 - s
            else:
                q = fa / fc
                r = fb / fc
                pp = s * (2.0 * xm * q * (q - r) - (xb - xa) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if pp > 0.0:
                q = -q
            pp = abs(pp)
            if 2.0 * pp < min(3.0 * xm * q - abs(tol * q), abs(e * q)):
                e = d
                d = pp / q
            else:
                d = xm
                e = d
        else:
            d = xm
            e = d
        xa, fa = xb, fb
        xb = xb + d if abs(d) > tol else xb + (tol if xm > 0 else -tol)
        fb = res(xb, *args)
    return xb, fb, -1
