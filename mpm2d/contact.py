"""Contact between velocity fields: rigid bodies, deformable bodies and the material.

Algorithm: multi-velocity-field contact (Bardenhagen, Brackbill and Sulsky 2000, "The
material-point method for granular materials", CMAME 187; York, Sulsky and Schreyer 2000;
Huang, Zhang, Sze and Wang 2011 for the momentum form), with a geometric gap criterion in the
manner of Nairn (Nairn 2013; Nairn, Bardenhagen and Smith 2018, "Generalized contact and
improved frictional heating in the material point method", Comp. Part. Mech. 5):

- every body has its own nodal field: a deformable body (a particle set listed in
  ``Simulation(contact_sets=...)``) its own mass and momentum, a rigid body its rigid motion
  u_i = V + omega e_z x (x_i - X) (its points' in-plane areas are scattered only to locate it);
  the material keeps its phase fields (one, or granular + fluid in two-phase mode);
- the contact normal at a node is the direction of the contact actually made there: the
  N-weighted mean of the face normals of the material points that touch the body (below),
  each the separating axis of its square and the nearest body point's square, pointing from
  the body into the material. Bardenhagen et al.'s normal from the nodal mass gradient
  g_i = sum_p m_p grad N_i(x_p) is the fallback where nothing touches (it follows the body's
  nearest face, sideways at a corner);
- contact is active at a node only if (i) both fields have mass there, (ii) the fields TOUCH, and
  (iii) they approach along n ((v_mat - v_body).n < 0). Touching: some material point whose
  B-spline support covers the node has its square (side s = sqrt(in-plane area)) touching or
  overlapping a body point's square (Chebyshev centre distance <= the sum of the half sides; a
  k-d tree of the body's points, rigid or deformable). Criterion (ii)
  removes the classic early contact of the multi-field method, whose fields overlap as soon as
  the shape-function supports (1.5 h for quadratic B-splines) do: a body h/4 above a bed feels
  nothing until its surface reaches the bed's particle faces (exact for grid-aligned faces;
  for a tilted face the point squares over-reach by up to (sqrt(2) - 1) s/2);
- a rigid body made with ``contact="mass"`` skips (ii) and takes the normal from its own area
  gradient (rigid_normals; the mirror fold zeroes its wall-normal component on a wall's nodes):
  the classic rule of Bardenhagen et al., as mpm_3d's ContactRigid_ReflectedBoundary has it. It
  acts wherever both fields have mass, i.e. from where the supports overlap (a gap below 2.25 h
  between faces on a lattice of h/2 with quadratic B-splines), before the surfaces meet;
- the contact impulse lambda on the material (equal and opposite on the body, so the total
  momentum is conserved exactly) makes the normal velocities equal (perfectly inelastic, no
  penetration), with Coulomb friction |lambda_t| <= mu_w lambda_n (mu_w = 0 frictionless,
  ``inf`` no-slip); lambda_n < 0 (tension) is never applied: the fields separate freely.

Rigid bodies: the impulses and the body's new velocity q = (V_x, V_y, omega) are found together,
implicitly, from M q = M (q^n + dt g) - sum_k J_k^T lambda_k with lambda_k = m_k P_k (J_k q - v_k*)
(P = 1 stick, n n^T frictionless, (n + s mu t) n^T sliding), by an active-set iteration (active
nodes, stick/slip states and tension release re-checked after each 3 x 3 solve): implicit in the
body mass (a light body on a heavy bed needs no added-mass step limit) and exactly
momentum-conserving. Nodes of fields a body is ``bonded_to`` (the spokes of a wheel on its hub)
are always in stick.

Deformable body against material: the closed-form two-field correction of Bardenhagen et al. at
each contact node (centre-of-mass velocity, normal part removed when approaching, tangential part
limited by mu_w times the normal impulse).

Limits: touching is judged between real points (mirror images across walls are not scanned;
periodic sides use minimum images); a point's square uses its current area, so anisotropic
stretching is not seen; a curved body's point faces are axis-aligned, so its frictionless normal
forces are only nearly central and its no-slip rolling resists.

Parameters: mu_w [-] the wall friction coefficient, in [0, inf] (per body); ``contact`` "touch"
(criterion (ii), default) or "mass" (rigid bodies); ``bonded_to`` the fields held in stick;
``Simulation(contact_sets=...)`` the particle sets that are deformable bodies.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from rheology.numba_cache import guard

from .grid import FX, FY, M, NOSLIP, PAD, SLIP, fold
from .shape import weights

guard(__file__)                          # drop cached kernels if a module they use changed
_jit = nb.njit(cache=True, error_model="numpy")

#: gap below which two fields touch [in units of h] (round-off of exactly touching faces)
GAP_TOL = 1e-9
#: active-set iterations of the rigid-body contact solve
MAX_ACTIVE_SET = 50


@_jit
def scatter_area_gradient(x, side, axisym, geo, out):
    """out[:, :, M] += N a_p and out[:, :, FX/FY] += grad N a_p, a_p = side_p^2 (in-plane area);
    nodes beyond the padded grid are skipped (a body reaching past the grid, where no material
    can be)."""
    x0, y0, h = geo[0], geo[1], geo[2]
    inv_h = 1.0 / h
    for p in range(x.shape[0]):
        bx, fx, wx0, wx1, wx2, dx0, dx1, dx2 = weights((x[p, 0] - x0) * inv_h)
        by, fy, wy0, wy1, wy2, dy0, dy1, dy2 = weights((x[p, 1] - y0) * inv_h)
        a = side[p] * side[p]
        for i in range(3):
            wa = wx0 if i == 0 else (wx1 if i == 1 else wx2)
            da = dx0 if i == 0 else (dx1 if i == 1 else dx2)
            for j in range(3):
                wb = wy0 if j == 0 else (wy1 if j == 1 else wy2)
                db = dy0 if j == 0 else (dy1 if j == 1 else dy2)
                I, J = bx + i + PAD, by + j + PAD
                if I < 0 or J < 0 or I >= out.shape[0] or J >= out.shape[1]:
                    continue
                out[I, J, M] += wa * wb * a
                out[I, J, FX] += da * wb * a * inv_h
                out[I, J, FY] += wa * db * a * inv_h


@_jit
def pair_contact(GA, GB, vA, vB, normal, gap, tol, mu, dt, force):
    """Bardenhagen two-field contact at every node where both fields have mass and touch.

    A is the body field, B the material; n points from A to B. On approach ((vA - vB).n > 0)
    the normal relative velocity is removed and the tangential impulse limited by mu |dp_n|
    (mu = inf: no slip). Momentum exchanged exactly; ``force`` (2,) += the force on A [N].
    """
    for I in range(GA.shape[0]):
        for J in range(GA.shape[1]):
            mA, mB = GA[I, J, M], GB[I, J, M]
            if mA <= 0.0 or mB <= 0.0 or not gap[I, J] <= tol:
                continue
            nx, ny = normal[I, J, 0], normal[I, J, 1]
            tx, ty = -ny, nx
            ms = mA + mB
            vcx = (mA * vA[I, J, 0] + mB * vB[I, J, 0]) / ms
            vcy = (mA * vA[I, J, 1] + mB * vB[I, J, 1]) / ms
            dpx, dpy = mA * (vcx - vA[I, J, 0]), mA * (vcy - vA[I, J, 1])   # no-slip impulse on A
            dpn = dpx * nx + dpy * ny
            if dpn >= 0.0:                   # not approaching: separate freely
                continue
            dpt = dpx * tx + dpy * ty
            lim = mu * (-dpn)
            if abs(dpt) > lim:
                dpt = lim if dpt > 0.0 else -lim
            px, py = dpn * nx + dpt * tx, dpn * ny + dpt * ty
            vA[I, J, 0] += px / mA
            vA[I, J, 1] += py / mA
            vB[I, J, 0] -= px / mB
            vB[I, J, 1] -= py / mB
            force[0] += px / dt
            force[1] += py / dt


def _mirror_kind(kind):
    """Boundary kinds for folding a geometric gradient: walls mirror like slip walls."""
    k = kind.copy()
    k[k == NOSLIP] = SLIP
    return k


class FieldGeometry:
    """Per-step geometry of one field on the grid: area sum_p N_ip a_p and the outward vector
    sum_p a_p grad N_i(x_p) (Bardenhagen's mass-gradient normal, unnormalised).

    Parameters
    ----------
    grid : Grid
    x : (N, 2) point positions [m]; side : (N,) point side sqrt(in-plane area) [m].
    """

    def __init__(self, grid, x, side, work):
        self.grid = grid
        work[:] = 0.0
        scatter_area_gradient(x, side, grid.axisymmetric, grid.geometry(), work)
        fold(work, _mirror_kind(grid.kind), np.zeros((4, 2)), grid.nx, grid.ny)
        self.area = work[:, :, M].copy()
        self.outward = work[:, :, FX:FY + 1].copy()
        self.x, self.side = x, side


@_jit
def rigid_normals(outward, node_x, node_y, cx, cy, out):
    """Unit outward normals of a rigid body at every node: its area-gradient vector, or where
    that vanishes (deep inside, far outside) the direction from the body's centre."""
    big = 0.0
    for I in range(outward.shape[0]):
        for J in range(outward.shape[1]):
            big = max(big, outward[I, J, 0] ** 2 + outward[I, J, 1] ** 2)
    tiny = 1e-24 * big
    for I in range(outward.shape[0]):
        for J in range(outward.shape[1]):
            ox, oy = outward[I, J, 0], outward[I, J, 1]
            n2 = ox * ox + oy * oy
            if n2 <= tiny or n2 == 0.0:
                ox, oy = node_x[I] - cx, node_y[J] - cy
                n2 = ox * ox + oy * oy
                if n2 == 0.0:
                    ox, oy, n2 = 0.0, 1.0, 1.0
            r = 1.0 / math.sqrt(n2)
            out[I, J, 0] = ox * r
            out[I, J, 1] = oy * r


def unit(v, fallback):
    """Row-normalised (NI, NJ, 2) vectors; ``fallback`` where |v| is ~0."""
    nrm = np.sqrt((v ** 2).sum(axis=2))
    big = nrm > 1e-12 * max(float(nrm.max()), 1e-300)
    out = np.where(big[..., None], v / np.where(big, nrm, 1.0)[..., None], fallback)
    return out


@_jit
def scatter_touch(x, nvec, geo, out):
    """out[:, :, M] += N_ip and out[:, :, FX/FY] += N_ip n_p for the touching points."""
    x0, y0, h = geo[0], geo[1], geo[2]
    inv_h = 1.0 / h
    for p in range(x.shape[0]):
        bx, fx, wx0, wx1, wx2, _, _, _ = weights((x[p, 0] - x0) * inv_h)
        by, fy, wy0, wy1, wy2, _, _, _ = weights((x[p, 1] - y0) * inv_h)
        for i in range(3):
            wa = wx0 if i == 0 else (wx1 if i == 1 else wx2)
            for j in range(3):
                wb = wy0 if j == 0 else (wy1 if j == 1 else wy2)
                I, J = bx + i + PAD, by + j + PAD
                if I < 0 or J < 0 or I >= out.shape[0] or J >= out.shape[1]:
                    continue
                w = wa * wb
                out[I, J, M] += w
                out[I, J, FX] += w * nvec[p, 0]
                out[I, J, FY] += w * nvec[p, 1]


@nb.njit(cache=True, inline="always")
def _neighbour_bin(b, d, periodic, n):
    """Index of the bin ``d`` (-1, 0, 1) away from bin ``b`` along an axis of ``n`` bins (wrapped
    if ``periodic``; an axis of fewer than 3 periodic bins is scanned once), or -1 if none."""
    k = b + d
    if periodic:
        return -1 if (n < 3 and d != 0) else k % n
    return k if 0 <= k < n else -1


@_jit
def _face_normals(fx, side, fb, sb, span, per, start, order, lo, width, nb, tol, slack, vec, hit):
    """For each material point (frame coordinates ``fx``, sides ``side``), the face contact with
    the nearest (Euclidean) body point whose square it touches across a face, from the body
    points binned in a cell list (bins ``width`` >= the largest contact distance, so only the
    3 x 3 neighbouring bins can hold a touching point; ``start``/``order`` the bins' CSR lists).
    Writes the separating axis's unit vector to ``vec[p]`` and ``hit[p]``."""
    for p in range(fx.shape[0]):
        S = 0.5 * (side[p] + sb)
        bi = [0, 0]
        for a in range(2):
            bi[a] = int(math.floor((fx[p, a] - lo[a]) / width[a]))
        best = np.inf
        bx = 0.0
        by = 0.0
        for di in range(-1, 2):
            i = _neighbour_bin(bi[0], di, per[0], nb[0])
            if i < 0:
                continue
            for dj in range(-1, 2):
                j = _neighbour_bin(bi[1], dj, per[1], nb[1])
                if j < 0:
                    continue
                c = i * nb[1] + j
                for q in range(start[c], start[c + 1]):
                    b = order[q]
                    dx = fx[p, 0] - fb[b, 0]
                    dy = fx[p, 1] - fb[b, 1]
                    if per[0]:
                        dx -= span[0] * np.round(dx / span[0])
                    if per[1]:
                        dy -= span[1] * np.round(dy / span[1])
                    ax, ay = abs(dx), abs(dy)
                    if max(ax, ay) - S <= tol and min(ax, ay) - S < -slack:
                        d2 = dx * dx + dy * dy
                        if d2 < best:
                            best, bx, by = d2, dx, dy
        hit[p] = best < np.inf
        if hit[p]:
            # the face's normal: the separating axis (largest |d|), from the body to the point
            if abs(bx) >= abs(by):
                vec[p, 0], vec[p, 1] = (1.0 if bx >= 0.0 else -1.0), 0.0
            else:
                vec[p, 0], vec[p, 1] = 0.0, (1.0 if by >= 0.0 else -1.0)


def touching(grid, body_x, body_side, pts, fallback, work):
    """Where a field touches a body, and the contact normal there.

    A material point touches the body if its square (side s_p) and a body point's square (side
    s_b) touch or overlap across a FACE: Chebyshev gap max(|dx|, |dy|) - (s_p + s_b)/2 <= tol
    with an overlap of the other axis (min(|dx|, |dy|) < (s_p + s_b)/2); squares meeting only at
    a corner do not count (a box sliding on a flat bed would otherwise collide with the bed point
    just beyond its leading corner). Its contact normal is the normal of that face (the
    separating axis, from the nearest touching body point towards it; the direction between the
    centres would tilt by up to 27 deg with the lateral offset of the two lattices, and a sliding
    block then ploughs). A node touches if a touching point covers it (B-spline support);
    its normal is the N-weighted mean of those points' normals: the direction of the actual
    contact, not of the body's nearest face (at a corner node the body's area gradient points
    sideways while the material touches its bottom). Periodic sides use minimum images.
    The body's points are searched through a cell list (bins as wide as the largest contact
    distance, rebuilt every call: O(points), compiled).

    Returns (touch (NI, NJ) bool, normal (NI, NJ, 2)); ``fallback`` gives the normal elsewhere.
    """
    geo = grid.geometry()
    h = grid.h
    per = np.array(grid.periodic)
    span = grid.upper - grid.lower

    def frame(x):
        y = x - grid.lower
        y[:, per] = np.mod(y[:, per], span[per])
        return y

    work[:] = 0.0
    fb = frame(np.array(body_x, dtype=float))
    sb = float(np.max(body_side))
    reach = 0.5 * (max((float(np.max(sd)) for _, sd in pts if len(sd)), default=0.0) + sb)
    reach = max(reach, 1e-12 * h) * (1.0 + 1e-9) + 2 * GAP_TOL * h
    lo = np.where(per, 0.0, fb.min(axis=0) - reach)
    ext = np.where(per, span, fb.max(axis=0) + reach - lo)
    nb = np.maximum(np.floor(ext / reach).astype(np.int64), 1)
    width = ext / nb
    cell = np.floor((fb - lo) / width).astype(np.int64)
    cell = np.minimum(np.maximum(cell, 0), nb - 1)
    key = cell[:, 0] * nb[1] + cell[:, 1]
    order = np.argsort(key, kind="stable")
    start = np.searchsorted(key[order], np.arange(nb[0] * nb[1] + 1))
    blo = body_x.min(axis=0) - 3.0 * h
    bhi = body_x.max(axis=0) + 3.0 * h
    blo[per], bhi[per] = -np.inf, np.inf
    for x, side in pts:
        near = np.all((x >= blo) & (x <= bhi), axis=1)
        if not near.any():
            continue
        xn = np.ascontiguousarray(x[near])
        vec = np.zeros((len(xn), 2))
        hit = np.zeros(len(xn), dtype=np.bool_)
        _face_normals(frame(xn), np.ascontiguousarray(side[near], dtype=float), fb, sb, span,
                      per, start, order, lo, width, nb, GAP_TOL * h, 1e-3 * h, vec, hit)
        if hit.any():
            scatter_touch(np.ascontiguousarray(xn[hit]), np.ascontiguousarray(vec[hit]), geo,
                          work)
    fold(work, _mirror_kind(grid.kind), np.zeros((4, 2)), grid.nx, grid.ny)
    touch = work[:, :, M] > 0.0
    normal = unit(work[:, :, FX:FY + 1], fallback)
    return touch, normal


def rigid_solve(body, entries, dt, gravity, h):
    """Implicit contact of one rigid body with the material (see module docstring).

    entries: list of dicts with I, J (node indices), m (k,), w (k, 2) predicted velocities
    (views to be corrected through ``vg``), n (k, 2) normals, bonded (bool), mu, vg (the field's
    velocity array). Writes the corrected nodal velocities, the body's velocity, force, torque.
    Returns the number of active-set iterations.
    """
    if entries:
        I = np.concatenate([e["I"] for e in entries])
        J = np.concatenate([e["J"] for e in entries])
        m = np.concatenate([e["m"] for e in entries])
        w = np.concatenate([e["w"] for e in entries])
        n = np.concatenate([e["n"] for e in entries])
        bonded = np.concatenate([np.full(e["I"].size, e["bonded"]) for e in entries])
        r = np.concatenate([e["r"] for e in entries])
    else:
        I = J = np.zeros(0, dtype=np.int64)
        m = np.zeros(0)
        w = n = r = np.zeros((0, 2))
        bonded = np.zeros(0, dtype=bool)
    mu = body.mu_w
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    g = np.asarray(gravity, dtype=float)
    Mb, Ib = body.mass, body.inertia
    Mdiag = np.array([Mb, Mb, Ib])
    q_old = np.array([body.velocity[0], body.velocity[1], body.omega])
    mq0 = Mdiag * (q_old + dt * np.array([g[0], g[1], 0.0]))
    free = body.free
    q = q_old.copy()
    q[:2][free[:2]] += dt * g[free[:2]]

    def rigid_u(qq):
        return np.stack([qq[0] - qq[2] * r[:, 1], qq[1] + qq[2] * r[:, 0]], axis=1)

    # status: 0 inactive, 1 stick, 2 sliding (s = sgn), bonded nodes always stick
    approach = np.einsum("ij,ij->i", w - rigid_u(q), n) < 0.0
    status = np.where(bonded, 1, np.where(approach, 1 if mu > 0.0 else 2, 0))
    sgn = np.zeros(I.size)
    it = 0
    for it in range(1, MAX_ACTIVE_SET + 1):
        act = status > 0
        # P_k = 1 (stick) or (n + s mu t) n^T (sliding); lambda = m P (J q - w)
        P = np.zeros((I.size, 2, 2))
        st = status == 1
        P[st] = np.eye(2)
        sl = status == 2
        if sl.any():
            mu_f = 0.0 if mu == 0.0 else mu
            dirv = n[sl] + (sgn[sl] * mu_f)[:, None] * t[sl]
            P[sl] = dirv[:, :, None] * n[sl][:, None, :]
        Jm = np.zeros((I.size, 2, 3))
        Jm[:, 0, 0] = 1.0
        Jm[:, 1, 1] = 1.0
        Jm[:, 0, 2] = -r[:, 1]
        Jm[:, 1, 2] = r[:, 0]
        mP = (m[act])[:, None, None] * P[act]
        A = np.diag(Mdiag) + np.einsum("kai,kab,kbj->ij", Jm[act], mP, Jm[act])
        b = mq0 + np.einsum("kai,kab,kb->i", Jm[act], mP, w[act])
        qn = q_old.copy()
        if free.any():
            Af = A[np.ix_(free, free)]
            bf = b[free] - A[np.ix_(free, ~free)] @ qn[~free]
            qn[free] = np.linalg.solve(Af, bf)
        q = qn
        u = rigid_u(q)
        lam = np.zeros((I.size, 2))
        lam[act] = np.einsum("kab,kb->ka", mP, (u - w)[act])
        ln = np.einsum("ij,ij->i", lam, n)
        lt = np.einsum("ij,ij->i", lam, t)
        new = status.copy()
        contact = ~bonded
        # release tension
        new[contact & act & (ln < -1e-14 * np.abs(lam).sum(axis=1).max(initial=0.0))] = 0
        if mu > 0.0 and np.isfinite(mu):
            slip = contact & (status == 1) & (np.abs(lt) > mu * ln) & (ln >= 0)
            new[slip] = 2
            sgn[slip] = np.sign(lt[slip])
            # a sliding node whose slip would reverse sticks again
            vrel = np.einsum("ij,ij->i", w + lam / m[:, None] - u, t)
            back = contact & (status == 2) & (sgn * vrel > 1e-14 * (1.0 + np.abs(vrel)))
            new[back] = 1
        # inactive nodes now approaching
        appr = contact & (status == 0) & (np.einsum("ij,ij->i", w - u, n) < 0.0)
        new[appr] = 1 if mu > 0.0 else 2
        if np.array_equal(new, status):
            break
        status = new
    impulse = lam
    vnew = w + impulse / np.where(m > 0, m, 1.0)[:, None]
    k0 = 0
    for e in entries:
        k1 = k0 + e["I"].size
        e["vg"][e["I"], e["J"]] = vnew[k0:k1]
        k0 = k1
    body.force = -impulse.sum(axis=0) / dt
    body.torque = -float(np.sum(r[:, 0] * impulse[:, 1] - r[:, 1] * impulse[:, 0])) / dt
    body.velocity = q[:2].copy()
    body.omega = float(q[2])
    body.contact_nodes = int((status > 0).sum())
    return it
