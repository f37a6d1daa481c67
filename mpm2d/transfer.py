"""Particle-to-grid and grid-to-particle transfers (numba kernels).

Transfer scheme: APIC (Jiang et al. 2015) by default. Each particle carries an affine velocity
matrix C_p besides v_p; P2G scatters m_p (v_p + C_p (x_i - x_p)), G2P gathers
v_p = sum_i N_ip v_i and C_p = D_p^-1 sum_i N_ip v_i (x_i - x_p)^T with D_p^-1 = 4/h^2 for quadratic
B-splines. The pair conserves linear AND angular momentum exactly and loses far less energy than
PIC (which discards every sub-cell velocity variation each step) without FLIP's noise (FLIP keeps
v_p + sum N (v_i^new - v_i^old), whose null-space modes are never damped: the ringing of the
paper's supplement). FLIP/PIC blends (alpha = 1 FLIP, 0 PIC; C_p = 0) are kept for comparison.

Race-free P2G: the particles are cut into ``nc`` contiguous chunks (particles are kept sorted by
cell, so a chunk is a compact region); each chunk scatters into its own private copy of the node
fields, and :func:`reduce_private` sums the copies in a fixed order. Results are therefore
deterministic and independent of the number of threads that run the chunks.

The stress enters the nodal force as f_i = -sum_p V_p sigma_p grad N_ip, plus, in axisymmetry
(x = r, volumes per radian V_p = r_p A_p), the hoop term -sum_p V_p sigma_thth N_ip / r_p. Under
gravity each point adds the well-balanced term m_p c_p h^2 d2N_ip/dx_k^2 g_k, which makes a bed
at rest an exact discrete equilibrium up to its free surface
(:func:`mpm2d.shape.hydrostatic_coefficient`).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rheology.numba_cache import guard

from .kernels import dual
from .grid import FPX, FPY, FX, FY, MX, MY, PAD, V, VS, M, FREE, PERIODIC
from .shape import APIC_D_INV, hydrostatic_coefficient, stencil, weights

guard(__file__)                          # drop cached kernels if a module they use changed
_jit = nb.njit(cache=True, error_model="numpy")


@_jit
def sort_order(x, geo, nrows):
    """Stable counting sort of points by B-spline base node (column-major keys).

    Returns the permutation, or an empty array if the points are already in order (the usual
    case between re-sorts: points move less than a cell per step).
    """
    x0, y0, inv_h = geo[0], geo[1], 1.0 / geo[2]
    n = x.shape[0]
    key = np.empty(n, dtype=np.int64)
    ordered = True
    kmin = kmax = 0
    for p in range(n):
        k = (int(np.floor((x[p, 0] - x0) * inv_h - 0.5)) + 2) * nrows + \
            int(np.floor((x[p, 1] - y0) * inv_h - 0.5)) + 2
        key[p] = k
        if p == 0:
            kmin = kmax = k
        else:
            if k < key[p - 1]:
                ordered = False
            kmin = min(kmin, k)
            kmax = max(kmax, k)
    if ordered:
        return np.empty(0, dtype=np.int64)
    count = np.zeros(kmax - kmin + 2, dtype=np.int64)
    for p in range(n):
        count[key[p] - kmin + 1] += 1
    for k in range(1, count.shape[0]):
        count[k] += count[k - 1]
    order = np.empty(n, dtype=np.int64)
    for p in range(n):
        k = key[p] - kmin
        order[count[k]] = p
        count[k] += 1
    return order


def chunk_bounds(n: int, nc: int) -> np.ndarray:
    """Start/stop indices of ``nc`` near-equal contiguous chunks of ``n`` particles."""
    return np.linspace(0, n, nc + 1).round().astype(np.int64)


@dual
def p2g(x, v, C, m, vol, sp, pf, fext, svol, geo, axisym, chunks, priv, ext, grav):
    """Scatter one particle set into the private node fields ``priv[c]`` of its chunks.

    Parameters
    ----------
    x, v : (N, 2) positions [m] and velocities [m/s]
    C : (N, 2, 2) APIC affine velocity [1/s] (zeros for FLIP/PIC)
    m, vol : (N,) mass [kg] and volume [m^3] (per radian in axisymmetry)
    sp : (N, 4) stress for the force (xx, xy, yy, thth) [Pa], tension positive
    pf : (N,) or (0,) pore pressure [Pa] of fluid points (two-phase), into FPX, FPY
    fext : (N, 4) or (0, 4) external force on each particle [N] (fx, fy) and the offset
        (ox, oy) [m] of the point where it acts (the face of a surface point for a traction)
    svol : (N,) or (0,) true solid volume of granular points (two-phase), into V and VS
    geo : (x0, y0, h, x1, y1)
    priv : (nc, NI, NJ, NF) private node fields, zero on entry
    ext : (nc, 2) written: per chunk, max V/m [m^3/kg] and max |v|^2 [m^2/s^2] of the points
        as scattered (the step size's wave and advection limits, taken in the same pass)
    grav : (2,) gravity [m/s^2], for the hydrostatic quadrature term only (the body force
        m_i g itself is added by :func:`reduce_private`); see :func:`hydrostatic_coefficient`

    Each point adds its 3 x 3 stencil straight into its chunk's copy (measured faster than
    summing runs of points with equal base nodes in a local block first). The hoop and
    hydrostatic terms are folded per stencil column/row (q_a, r_b below) so that each node costs
    one multiply-add for each.
    """
    nc = chunks.shape[0] - 1
    x0, y0, h = geo[0], geo[1], geo[2]
    inv_h = 1.0 / h
    has_p, has_f, has_s = pf.shape[0] > 0, fext.shape[0] > 0, svol.shape[0] > 0
    nf = priv.shape[3]
    grx, gry = grav[0], grav[1]
    has_g = grx != 0.0 or gry != 0.0
    for c in nb.prange(nc):
        G = priv[c]
        e_vm = e_v2 = 0.0
        for p in range(chunks[c], chunks[c + 1]):
            bx, by, fx, fy, wx, wy, dx, dy = stencil(x[p, 0], x[p, 1], x0, y0, inv_h)
            mp, Vp = m[p], vol[p]
            e_vm = max(e_vm, Vp / mp)
            e_v2 = max(e_v2, v[p, 0] * v[p, 0] + v[p, 1] * v[p, 1])
            mvx, mvy = mp * v[p, 0], mp * v[p, 1]
            c00, c01 = mp * h * C[p, 0, 0], mp * h * C[p, 0, 1]
            c10, c11 = mp * h * C[p, 1, 0], mp * h * C[p, 1, 1]
            sxx, sxy, syy = Vp * sp[p, 0] * inv_h, Vp * sp[p, 1] * inv_h, Vp * sp[p, 2] * inv_h
            hoop = Vp * sp[p, 3] / x[p, 0] if axisym else 0.0
            ch = hydrostatic_coefficient(Vp / x[p, 0] if axisym else Vp, h) if has_g else 0.0
            kgx, kgy = ch * mp * grx, ch * mp * gry
            # the term on an outer stencil node is limited where the point's weight there is
            # below ch/2 (never in a regular layout, whose smallest weight is ch = 1/(8 n^2)),
            # the middle node taking the rest (the sum stays 0): N'' stays 1/h^2 where the
            # node's mass share goes to 0, an unbounded acceleration of a node that only such a
            # point reaches (a free surface after deformation; the wheel scene's stops)
            lim = 2.0 / ch if ch > 0.0 else 0.0
            sx0, sx2 = min(1.0, wx[0] * lim), min(1.0, wx[2] * lim)
            sy0, sy2 = min(1.0, wy[0] * lim), min(1.0, wy[2] * lim)
            # FX: - w hoop + kgx h^2 N'' = wy_b q_a; FY: kgy wx_a h^2 N''_b = wx_a r_b
            q = (kgx * sx0 - wx[0] * hoop, -kgx * (sx0 + sx2) - wx[1] * hoop,
                 kgx * sx2 - wx[2] * hoop)
            r = (kgy * sy0, -kgy * (sy0 + sy2), kgy * sy2)
            two = nf > V                             # two-phase fields: V, VS, FPX, FPY
            pp = Vp * pf[p] * inv_h if has_p else 0.0
            hoop_p = Vp * pf[p] / x[p, 0] if (has_p and axisym) else 0.0
            sv = svol[p] if has_s else 0.0
            for a in range(3):
                I = bx + a + PAD
                rx = a - fx                          # (x_i - x_p)/h
                mxa, mya = mvx + c00 * rx, mvy + c10 * rx
                for b in range(3):
                    J = by + b + PAD
                    ry = b - fy
                    w = wx[a] * wy[b]
                    gx = dx[a] * wy[b]               # h dN/dx
                    gy = wx[a] * dy[b]
                    G[I, J, M] += w * mp
                    G[I, J, MX] += w * (mxa + c01 * ry)
                    G[I, J, MY] += w * (mya + c11 * ry)
                    G[I, J, FX] += q[a] * wy[b] - (sxx * gx + sxy * gy)
                    G[I, J, FY] += r[b] * wx[a] - (sxy * gx + syy * gy)
                    if two:              # (VS: grains only; FPX, FPY: fluid points only)
                        G[I, J, V] += w * Vp
                        if has_s:
                            G[I, J, VS] += w * sv
                        if has_p:
                            G[I, J, FPX] += pp * gx + w * hoop_p
                            G[I, J, FPY] += pp * gy
            if has_f and (fext[p, 0] != 0.0 or fext[p, 1] != 0.0):
                # a surface load acts on the point's face x_p + offset, where the particle
                # quadrature of the internal force puts the boundary (exact for B-splines)
                ex, _, ex0, ex1, ex2, _, _, _ = weights((x[p, 0] + fext[p, 2] - x0) * inv_h)
                ey, _, ey0, ey1, ey2, _, _, _ = weights((x[p, 1] + fext[p, 3] - y0) * inv_h)
                ew = (ex0, ex1, ex2)
                eh = (ey0, ey1, ey2)
                for a in range(3):
                    for b in range(3):
                        G[ex + a + PAD, ey + b + PAD, FX] += ew[a] * eh[b] * fext[p, 0]
                        G[ex + a + PAD, ey + b + PAD, FY] += ew[a] * eh[b] * fext[p, 1]
        ext[c, 0], ext[c, 1] = e_vm, e_v2


@nb.njit(cache=True, error_model="numpy", inline="always")
def sum_chunks(priv, out, I, J):
    """out[I, J, :] = sum over chunks of priv[:, I, J, :] (fixed order), then priv := 0 there."""
    for k in range(priv.shape[3]):
        s = 0.0
        for c in range(priv.shape[0]):
            s += priv[c, I, J, k]
            priv[c, I, J, k] = 0.0
        out[I, J, k] = s


@dual
def reduce_private(priv, out, gravity, gx, gy):
    """out = sum over chunks of priv (fixed order), then priv := 0; with ``gravity`` also the
    body force f_i += m_i g (out[..., FX/FY] += out[..., M] (gx, gy)), in the same pass (before
    folding, so that images see mirrored gravity)."""
    NI, NJ = priv.shape[1], priv.shape[2]
    for I in nb.prange(NI):
        for J in range(NJ):
            sum_chunks(priv, out, I, J)
            if gravity:
                out[I, J, FX] += out[I, J, M] * gx
                out[I, J, FY] += out[I, J, M] * gy


@nb.njit(cache=True, error_model="numpy", inline="always")
def node_velocity(G, I, J, dt, vg, vg_old, old):
    """v* = (p + dt f)/m at node (I, J) (0 without mass), and with ``old`` v_old = p/m: the
    arithmetic of mpm2d.grid_update.velocities, node by node."""
    m = G[I, J, M]
    if m > 0.0:
        if old:
            vg_old[I, J, 0] = G[I, J, MX] / m
            vg_old[I, J, 1] = G[I, J, MY] / m
        vg[I, J, 0] = (G[I, J, MX] + dt * G[I, J, FX]) / m
        vg[I, J, 1] = (G[I, J, MY] + dt * G[I, J, FY]) / m
    else:
        if old:
            vg_old[I, J, 0] = vg_old[I, J, 1] = 0.0
        vg[I, J, 0] = vg[I, J, 1] = 0.0


@dual
def reduce_velocities(priv, out, gx, gy, dt, vg, vg_old, old):
    """:func:`reduce_private` with the body force, and the nodal velocities
    (:func:`node_velocity`) in the same pass over the grid.

    For a field whose only change between the reduction and the velocities is the boundary fold
    (one velocity field, no axis correction, no swirl): the velocities of the nodes the fold
    changes are then recomputed by :func:`boundary_velocities`. Same values as reduce, fold,
    velocities in turn."""
    NI, NJ = priv.shape[1], priv.shape[2]
    for I in nb.prange(NI):
        for J in range(NJ):
            sum_chunks(priv, out, I, J)
            out[I, J, FX] += out[I, J, M] * gx
            out[I, J, FY] += out[I, J, M] * gy
            node_velocity(out, I, J, dt, vg, vg_old, old)


@_jit
def boundary_velocities(G, dt, vg, vg_old, old):
    """:func:`node_velocity` on the nodes a fold can change: the 2 PAD + 1 outer node lines
    of each side (ghosts, wall node and the PAD nodes inside it, or a periodic band)."""
    NI, NJ = G.shape[0], G.shape[1]
    band = 2 * PAD + 1
    for I in range(NI):
        edge_i = I < band or I >= NI - band
        for J in range(NJ):
            if edge_i or J < band or J >= NJ - band:
                node_velocity(G, I, J, dt, vg, vg_old, old)


@dual
def g2p(x, v, C, L, vg, vg_old, geo, axisym, apic, flip_alpha, dt, kind, flag):
    """Gather grid velocities to one particle set and move it.

    Writes v (APIC/PIC: sum N v_i; FLIP blend: alpha (v_p + sum N (v_i - v_i^old)) +
    (1 - alpha) sum N v_i), C (APIC only), L = grad v as (N, 5) = (xx, xy, yx, yy, thth) with
    L_ab = d v_a / d x_b and L_thth = v_r / r in axisymmetry, and x += dt sum N v_i.
    Particles crossing a wall are reflected back, periodic ones wrapped; a particle leaving a
    free side's ghost layer sets ``flag[0] = 1``. The per-point work is :func:`gather_point`
    (shared with the fused gather + elastic update, mpm2d.materials.elastic_g2p_kernel).
    """
    for p in nb.prange(x.shape[0]):
        L[p, 0], L[p, 1], L[p, 2], L[p, 3], L[p, 4] = gather_point(
            p, x, v, C, vg, vg_old, geo, axisym, apic, flip_alpha, dt, kind, flag)


@nb.njit(cache=True, error_model="numpy", inline="always")
def gather_point(p, x, v, C, vg, vg_old, geo, axisym, apic, flip_alpha, dt, kind, flag):
    """G2P of point p (see :func:`g2p`): v, C and the new position of point p; returns its L
    (xx, xy, yx, yy, thth), which the caller stores or uses in registers."""
    x0, y0, h, x1, y1 = geo[0], geo[1], geo[2], geo[3], geo[4]
    inv_h = 1.0 / h
    dinv = APIC_D_INV * inv_h          # D^-1 (x_i - x_p) with (x_i - x_p) in cell units
    lo_x, hi_x = x0 - 1.4 * h, x1 + 1.4 * h
    lo_y, hi_y = y0 - 1.4 * h, y1 + 1.4 * h
    bx, by, fx, fy, wx, wy, dx, dy = stencil(x[p, 0], x[p, 1], x0, y0, inv_h)
    # separable sums: along each stencil column a, the sums over b of u weighted by N_b,
    # N_b (y_b - y_p)/h and h dN_b/dy, then over a with N_a, N_a (x_a - x_p)/h and h dN_a/dx
    wry = (-fy * wy[0], (1.0 - fy) * wy[1], (2.0 - fy) * wy[2])
    vx = vy = 0.0
    bxx = bxy = byx = byy = 0.0
    lxx = lxy = lyx = lyy = 0.0
    for a in range(3):
        I = bx + a + PAD
        s0x = s1x = s2x = s0y = s1y = s2y = 0.0
        for b in range(3):
            J = by + b + PAD
            ux, uy = vg[I, J, 0], vg[I, J, 1]
            s0x += wy[b] * ux
            s0y += wy[b] * uy
            s1x += wry[b] * ux
            s1y += wry[b] * uy
            s2x += dy[b] * ux
            s2y += dy[b] * uy
        wa, wr, da = wx[a], wx[a] * (a - fx), dx[a]
        vx += wa * s0x
        vy += wa * s0y
        bxx += wr * s0x
        byx += wr * s0y
        bxy += wa * s1x
        byy += wa * s1y
        lxx += da * s0x
        lyx += da * s0y
        lxy += wa * s2x
        lyy += wa * s2y
    l4 = vx / x[p, 0] if axisym else 0.0
    if apic:
        C[p, 0, 0], C[p, 0, 1] = dinv * bxx, dinv * bxy
        C[p, 1, 0], C[p, 1, 1] = dinv * byx, dinv * byy
        v[p, 0], v[p, 1] = vx, vy
    else:
        ox = oy = 0.0
        for a in range(3):
            for b in range(3):
                w = wx[a] * wy[b]
                ox += w * vg_old[bx + a + PAD, by + b + PAD, 0]
                oy += w * vg_old[bx + a + PAD, by + b + PAD, 1]
        v[p, 0] = flip_alpha * (v[p, 0] + vx - ox) + (1.0 - flip_alpha) * vx
        v[p, 1] = flip_alpha * (v[p, 1] + vy - oy) + (1.0 - flip_alpha) * vy
    xn = x[p, 0] + dt * vx
    yn = x[p, 1] + dt * vy
    xn = _keep_inside(xn, x0, x1, kind[0], kind[1])
    yn = _keep_inside(yn, y0, y1, kind[2], kind[3])
    if not (lo_x < xn < hi_x and lo_y < yn < hi_y):
        flag[0] = 1
    x[p, 0], x[p, 1] = xn, yn
    return lxx * inv_h, lxy * inv_h, lyx * inv_h, lyy * inv_h, l4


@_jit
def _keep_inside(s, lo, hi, kind_lo, kind_hi):
    """Reflect a coordinate back through a wall, or wrap it on a periodic axis."""
    if kind_lo == PERIODIC:
        span = hi - lo
        if s < lo:
            s += span
        elif s >= hi:
            s -= span
        return s
    if kind_lo != FREE and s < lo:
        s = 2.0 * lo - s
    if kind_hi != FREE and s > hi:
        s = 2.0 * hi - s
    return s




@dual
def gather_scalar_vector(x, s_nodes, q_nodes, geo, axisym, s_out, div_out):
    """Interpolate a nodal scalar and the divergence of a nodal vector field to points.

    s_out = sum N_i s_i; div_out = sum q_i . grad N_i (+ q_r/r in axisymmetry). Used for the
    porosity and the divergence of the mixture volume flux at the fluid points.
    """
    x0, y0, h = geo[0], geo[1], geo[2]
    inv_h = 1.0 / h
    for p in nb.prange(x.shape[0]):
        bx, by, fx, fy, wx, wy, dx, dy = stencil(x[p, 0], x[p, 1], x0, y0, inv_h)
        s = dv = qr = 0.0
        for a in range(3):
            wa, da = wx[a], dx[a]
            for b in range(3):
                wb, db = wy[b], dy[b]
                I, J = bx + a + PAD, by + b + PAD
                w = wa * wb
                s += w * s_nodes[I, J]
                dv += (q_nodes[I, J, 0] * da * wb + q_nodes[I, J, 1] * wa * db) * inv_h
                qr += w * q_nodes[I, J, 0]
        s_out[p] = s
        div_out[p] = dv + (qr / x[p, 0] if axisym else 0.0)



@_jit
def wall_moments(x, vol, s, geo, lo_band, hi_band, out):
    """Radial-wall moments of a set's stress for the axisymmetric wall correction.

    For the points within ``lo_band`` [m] of the grid's xmin side or ``hi_band`` of its xmax side
    (0: none), scatters into the unfolded node fields ``out`` (NI, NJ, NF_TWO), to be folded like
    the forces::

        out[M]  += N_ip A_p          out[V] += N_ip A_p s_p   (both fold evenly)
        out[FX] += A_p (r_p dN_ip/dr + N_ip)     (minus the radial force of a unit uniform
                                                   stress sigma_rr = sigma_thth = 1)

    with A_p = V_p/r_p the in-plane area and s_p the point's (sigma_rr + sigma_thth)/2.
    """
    x0, y0, h, x1 = geo[0], geo[1], geo[2], geo[3]
    inv_h = 1.0 / h
    for p in range(x.shape[0]):
        r = x[p, 0]
        if not ((lo_band > 0.0 and r < x0 + lo_band) or (hi_band > 0.0 and r > x1 - hi_band)):
            continue
        A = vol[p] / r
        bx, fx, wx0, wx1, wx2, dx0, dx1, dx2 = weights((r - x0) * inv_h)
        by, fy, wy0, wy1, wy2, _, _, _ = weights((x[p, 1] - y0) * inv_h)
        for a in range(3):
            wa = wx0 if a == 0 else (wx1 if a == 1 else wx2)
            da = dx0 if a == 0 else (dx1 if a == 1 else dx2)
            for b in range(3):
                wb = wy0 if b == 0 else (wy1 if b == 1 else wy2)
                I, J = bx + a + PAD, by + b + PAD
                out[I, J, M] += wa * wb * A
                out[I, J, V] += wa * wb * A * s[p]
                out[I, J, FX] += A * (r * da * inv_h + wa) * wb


# ---------------------------------------------------------------------- swirl (opt-in)
@dual
def p2g_swirl(x, m, vol, vth, Cl, spw, geo, chunks, priv):
    """Scatter the azimuthal motion of one set into private fields ``priv`` (nc, NI, NJ, 3).

    Axisymmetric swirl carried as the angular momentum per unit mass l = r v_theta, whose
    balance needs no Coriolis term (it is the -rho v_r v_theta / r of the v_theta equation)::

        rho Dl/Dt = (1/r) d(r^2 sigma_r_theta)/dr + r d(sigma_theta_z)/dz

    Weak form with the per-radian volumes V_p = r_p A_p:

        priv[..., 0] += N_ip m_p (l_p + Cl_p . (x_i - x_p))        (APIC angular momentum)
        priv[..., 1] += -V_p r_p (sigma_rt dN_ip/dr + sigma_tz dN_ip/dz)   (torque [N m])
        priv[..., 2] += N_ip m_p v_theta^2 / r_p                   (centrifugal radial force)

    Shapes: x (N, 2) [m], m, vol (N,), vth (N,) [m/s], Cl (N, 2) [m/s], spw (N, 2) [Pa].
    """
    nc = chunks.shape[0] - 1
    x0, y0, h = geo[0], geo[1], geo[2]
    inv_h = 1.0 / h
    for c in nb.prange(nc):
        G = priv[c]
        for p in range(chunks[c], chunks[c + 1]):
            bx, by, fx, fy, wx, wy, dx, dy = stencil(x[p, 0], x[p, 1], x0, y0, inv_h)
            r = x[p, 0]
            mp = m[p]
            ml = mp * r * vth[p]
            c0, c1 = mp * h * Cl[p, 0], mp * h * Cl[p, 1]
            tr, tz = vol[p] * r * spw[p, 0] * inv_h, vol[p] * r * spw[p, 1] * inv_h
            fc = mp * vth[p] * vth[p] / r
            for a in range(3):
                rx = a - fx
                for b in range(3):
                    ry = b - fy
                    w = wx[a] * wy[b]
                    I, J = bx + a + PAD, by + b + PAD
                    G[I, J, 0] += w * (ml + c0 * rx + c1 * ry)
                    G[I, J, 1] -= tr * dx[a] * wy[b] + tz * wx[a] * dy[b]
                    G[I, J, 2] += w * fc


@dual
def g2p_swirl(x, vth, Cl, Lw, lg, lg_old, geo, apic, alpha):
    """Gather the nodal l = r v_theta to one set (call before :func:`g2p` moves the points).

    l_p = sum N_ip l_i + alpha (r_p v_theta - sum N_ip l_i^old), then v_theta = l_p / r_p, with
    ``lg_old`` the nodal l before this step's torque: alpha = 0 is APIC or PIC, alpha > 0 keeps
    that fraction of what the point carries beyond the grid's interpolant (FLIP/PIC blend
    without ``apic``, the APIC-FLIP blend of Fei et al. 2021 with it). Cl = D^-1 sum N_ip l_i
    (x_i - x_p) (APIC, else 0); Lw = (dv_theta/dr - v_theta/r, dv_theta/dz) = (l_r/r - 2 l/r^2,
    l_z/r) with l, l_r, l_z = sum l_i (N_ip, grad N_ip): the swirl rates in the basis turning
    with the point.

    Why the blend: APIC and PIC replace a point's l by the grid interpolant every step, which
    damps what the grid does not represent (PIC all but the interpolant, APIC all but its affine
    part) once per step, so at fixed h the damping of a shear wave grows as dt falls (measured,
    see mpm2d.scenes.annular). Both blends conserve sum m_p l_p exactly (the alpha term sums to
    zero with lumped masses). Shapes: x (N, 2) [m], vth (N,) [m/s] in/out, Cl, Lw (N, 2) out,
    lg, lg_old (NI, NJ) [m^2/s]; lg_old is not read when alpha = 0.
    """
    x0, y0, h = geo[0], geo[1], geo[2]
    inv_h = 1.0 / h
    dinv = APIC_D_INV * inv_h
    blend = alpha > 0.0
    for p in nb.prange(x.shape[0]):
        bx, by, fx, fy, wx, wy, dx, dy = stencil(x[p, 0], x[p, 1], x0, y0, inv_h)
        l = lr = lz = br = bz = lo = 0.0
        for a in range(3):
            rx = a - fx
            for b in range(3):
                ry = b - fy
                li = lg[bx + a + PAD, by + b + PAD]
                w = wx[a] * wy[b]
                l += w * li
                br += w * li * rx
                bz += w * li * ry
                lr += li * dx[a] * wy[b]
                lz += li * wx[a] * dy[b]
                if blend:
                    lo += w * lg_old[bx + a + PAD, by + b + PAD]
        r = x[p, 0]
        Lw[p, 0] = lr * inv_h / r - 2.0 * l / (r * r)
        Lw[p, 1] = lz * inv_h / r
        if blend:
            vth[p] = (l + alpha * (r * vth[p] - lo)) / r
        else:
            vth[p] = l / r
        if apic:
            Cl[p, 0], Cl[p, 1] = dinv * br, dinv * bz
        else:
            Cl[p, 0] = Cl[p, 1] = 0.0
