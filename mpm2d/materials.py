"""Materials of the material points and their constitutive update kernels.

Each material knows its phase (``solid``: granular phase or a body; ``fluid``: the pore fluid of a
two-phase run), sets the points' masses and state, and advances them over a step from the
velocity gradient L gathered by the grid-to-particle transfer (USL: the stress is updated last,
with the new grid velocities). The stress used by the next particle-to-grid transfer is written to
``sp`` = (xx, xy, yy, thth/zz). The physics comes from :mod:`rheology`:

- :class:`LinearElastic`: Jaumann-rate linear elasticity, ``rheology.local_update.jaumann_elastic``.
- :class:`NewtonianFluid`: Table 8 fluid: p_f = kappa ln(rho_f/rho_0f), tau_f = eta0 (1 + 5/2 phi)
  (L + L^T - 2/3 tr L 1); true density from Table 8's law (n/rho_f) D rho_f/Dt = -div q,
  q = phi v_s + n v_f the mixture volume flux (q = v for a single fluid).
- :class:`Suspension`: the Table 8 granular law through ``rheology.local_update.update_block``,
  never re-implemented. ``locked=True`` is the locked mixture (one velocity field): the points
  carry the mixture mass, and the stress sigma~ - p_f 1 + tau_f with the undrained pore pressure
  of their fluid (rho_f = fluid mass / pore volume).

Volumes follow V_{n+1} = V_n det(1 + dt L) (3 x 3, with L_thth = v_r/r in axisymmetry).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rheology import laws, vecmath
from runkit.params import check_positive, check_range
from rheology.flow_rule import invariants
from rheology.local_update import (BLOCK, FAILED, NOUT, NSTRESS, NWORK, jaumann_elastic,
                                   jaumann_elastic_plane, kernel_parameters, update_block)
from rheology.materials import Material
from rheology.numba_cache import guard

from .kernels import dual
from .transfer import gather_point

guard(__file__)                          # drop cached kernels if rheology's laws changed

_jit = nb.njit(cache=True, error_model="numpy")


# ------------------------------------------------------------------ shared kernel pieces
_inline = nb.njit(cache=True, error_model="numpy", inline="always")


@_inline
def _det(l0, l1, l2, l3, l4, dt):
    """det(1 + dt L) of a compact gradient (xx, xy, yx, yy, thth)."""
    return ((1.0 + dt * l0) * (1.0 + dt * l3) - dt * dt * l1 * l2) * (1.0 + dt * l4)


@_inline
def _jacobian(L, p, dt):
    """det(1 + dt L) for the compact gradient row p."""
    return _det(L[p, 0], L[p, 1], L[p, 2], L[p, 3], L[p, 4], dt)


@_inline
def _viscous(L, p, eta):
    """tau = eta (L + L^T - 2/3 tr L 1) as (xx, xy, yy, thth)."""
    tr = L[p, 0] + L[p, 3] + L[p, 4]
    return (eta * (2.0 * L[p, 0] - 2.0 / 3.0 * tr), eta * (L[p, 1] + L[p, 2]),
            eta * (2.0 * L[p, 3] - 2.0 / 3.0 * tr), eta * (2.0 * L[p, 4] - 2.0 / 3.0 * tr))


# ------------------------------------------------------------------ kernels
@nb.njit(cache=True, error_model="numpy", inline="always")
def _elastic_point(stress, l, vol, dt, G, K, sp, Lw, spw, p):
    """Jaumann linear-elastic update of point p in registers from its compact gradient l (the
    5-tuple xx, xy, yx, yy, thth): with swirl rheology.local_update.jaumann_elastic on the 3 x 3
    L of l and the swirl rows L_theta_r, L_theta_z (zeros above them); without, the plane form
    (jaumann_elastic_plane: no out-of-plane shear, which Simulation checks at the start, so the
    four in-plane and hoop components are the whole update)."""
    l0, l1, l2, l3, l4 = l
    if Lw.shape[0] > 0:
        r = jaumann_elastic((stress[p, 0, 0], stress[p, 0, 1], stress[p, 0, 2],
                             stress[p, 1, 0], stress[p, 1, 1], stress[p, 1, 2],
                             stress[p, 2, 0], stress[p, 2, 1], stress[p, 2, 2]),
                            (l0, l1, 0.0, l2, l3, 0.0, Lw[p, 0], Lw[p, 1], l4), dt, G, K)
        stress[p, 0, 0], stress[p, 0, 1], stress[p, 0, 2] = r[0], r[1], r[2]
        stress[p, 1, 0], stress[p, 1, 1], stress[p, 1, 2] = r[3], r[4], r[5]
        stress[p, 2, 0], stress[p, 2, 1], stress[p, 2, 2] = r[6], r[7], r[8]
        sp[p, 0], sp[p, 1], sp[p, 2], sp[p, 3] = r[0], r[1], r[4], r[8]
        spw[p, 0], spw[p, 1] = r[2], r[5]
    else:
        n00, n01, n11, n22 = jaumann_elastic_plane(stress[p, 0, 0], stress[p, 0, 1],
                                                   stress[p, 1, 1], stress[p, 2, 2], l0, l1, l2,
                                                   l3, l4, dt, G, K)
        stress[p, 0, 0], stress[p, 0, 1], stress[p, 1, 0] = n00, n01, n01
        stress[p, 1, 1], stress[p, 2, 2] = n11, n22
        sp[p, 0], sp[p, 1], sp[p, 2], sp[p, 3] = n00, n01, n11, n22
    vol[p] *= _det(l0, l1, l2, l3, l4, dt)


@dual
def elastic_kernel(stress, L, vol, dt, G, K, sp, Lw, spw):
    """Jaumann linear-elastic update of every point; sp = (xx, xy, yy, zz); with swirl (Lw,
    spw of shape (N, 2), else (0, 2)) spw = (r theta, theta z)."""
    for p in nb.prange(vol.shape[0]):
        _elastic_point(stress, (L[p, 0], L[p, 1], L[p, 2], L[p, 3], L[p, 4]), vol, dt, G, K, sp,
                       Lw, spw, p)


@dual
def elastic_g2p_kernel(x, v, C, L, vg, vg_old, geo, axisym, apic, flip_alpha, dt, kind, flag,
                       stress, vol, G, K, sp, Lw, spw):
    """G2P (:func:`mpm2d.transfer.g2p`, same arguments first) and the linear-elastic update
    (:func:`elastic_kernel`, same arguments after) of each point in one pass: the point's L is
    used while it is in registers, and the step has one parallel loop fewer. Same arithmetic in
    the same order per point as the two kernels called one after the other, so the results are
    identical to them."""
    for p in nb.prange(x.shape[0]):
        l = gather_point(p, x, v, C, vg, vg_old, geo, axisym, apic, flip_alpha, dt, kind, flag)
        L[p, 0], L[p, 1], L[p, 2], L[p, 3], L[p, 4] = l
        _elastic_point(stress, l, vol, dt, G, K, sp, Lw, spw, p)


@dual
def fluid_kernel(L, vol, m, rho, divq, n, dt, eta0, einstein, rho0, kappa, two_phase, sp, pf,
                 Lw, spw):
    """Newtonian fluid points: density, pore pressure and viscous stress.

    Two phases: rho_f *= exp(-dt div q / n) (Table 8 true-density law), sp = tau_f, pf = p_f.
    One phase: rho = m/V exactly, sp = tau - p 1. With swirl (Lw, spw (N, 2), else (0, 2)):
    spw = eta (L_theta_r, L_theta_z) = (tau_r_theta, tau_theta_z).
    """
    sw = Lw.shape[0] > 0
    N = vol.shape[0]
    for c in nb.prange((N + BLOCK - 1) // BLOCK):
        lo, hi = c * BLOCK, min((c + 1) * BLOCK, N)
        for p in range(lo, hi):
            vol[p] *= _jacobian(L, p, dt)
        # density and pore pressure in loops of their own over the block's slices (indices from
        # 0, so no negative-index wraparound: rheology.vecmath's log and exp compile to SIMD)
        rc, vc, pc = rho[lo:hi], vol[lo:hi], pf[lo:hi]
        if two_phase:
            qc, nc = divq[lo:hi], n[lo:hi]
            for k in range(hi - lo):
                rc[k] *= vecmath.exp(-dt * qc[k] / nc[k])
        else:
            mc = m[lo:hi]
            for k in range(hi - lo):
                rc[k] = mc[k] / vc[k]
        for k in range(hi - lo):
            pc[k] = laws.pore_pressure(rc[k], rho0, kappa)
        for p in range(lo, hi):
            phi = 1.0 - n[p] if two_phase else 0.0
            eta = laws.fluid_viscosity(phi, eta0) if einstein else eta0
            txx, txy, tyy, ttt = _viscous(L, p, eta)
            if sw:
                spw[p, 0], spw[p, 1] = eta * Lw[p, 0], eta * Lw[p, 1]
            # two phases: the pore pressure goes through pf (buoyancy split), not sp
            pr = 0.0 if two_phase else pf[p]
            sp[p, 0], sp[p, 1], sp[p, 2], sp[p, 3] = txx - pr, txy, tyy - pr, ttt - pr


@nb.njit(cache=True, error_model="numpy", inline="always")
def _trial(stress, L, Lw, p, dt, G, K, S, k):
    """The Jaumann trial stress of point p into column k of update_block's stress S: with swirl
    rheology.local_update.jaumann_elastic on the 3 x 3 L of the compact row and the swirl rows,
    without the plane form (four components; sigma_xz = sigma_yz = 0)."""
    if Lw.shape[0] > 0:
        r = jaumann_elastic((stress[p, 0, 0], stress[p, 0, 1], stress[p, 0, 2],
                             stress[p, 1, 0], stress[p, 1, 1], stress[p, 1, 2],
                             stress[p, 2, 0], stress[p, 2, 1], stress[p, 2, 2]),
                            (L[p, 0], L[p, 1], 0.0, L[p, 2], L[p, 3], 0.0, Lw[p, 0], Lw[p, 1],
                             L[p, 4]), dt, G, K)
        S[0, k], S[1, k], S[2, k], S[3, k], S[4, k], S[5, k] = r[0], r[4], r[8], r[1], r[2], r[5]
    else:
        n00, n01, n11, n22 = jaumann_elastic_plane(stress[p, 0, 0], stress[p, 0, 1],
                                                   stress[p, 1, 1], stress[p, 2, 2], L[p, 0],
                                                   L[p, 1], L[p, 2], L[p, 3], L[p, 4], dt, G, K)
        S[0, k], S[1, k], S[2, k], S[3, k], S[4, k], S[5, k] = n00, n11, n22, n01, 0.0, 0.0


#: the trial stage of update_block, public for validation/bench_mpm2d (which times each stage)
trial_stress = _trial


@dual
def suspension_kernel(stress, L, vol, svol, m, f, dt, P, locked, rho_s, rho_f0, kappa, eta0,
                      sp, pf, gdot, case, fail, Lw, spw, S, W, blk, none):
    """The Table 8 granular law at every point (rheology.local_update.update_block on blocks of
    BLOCK points, dealt round-robin to S.shape[0] lanes, a few per thread: the cost of a point
    varies several times with its case, so contiguous equal shares of the points, one a thread,
    would leave threads waiting while one finishes an expensive region).

    phi = svol/V at the start of the step; f and stress advanced; V *= det(1 + dt L).
    Locked mixture: pore pressure p_f = kappa ln(rho_f/rho_0f) with rho_f = (m - rho_s svol) /
    (V - svol) (undrained), fluid stress eta0 (1 + 5/2 phi)(L + L^T - 2/3 tr L), and
    sp = sigma~ - p_f 1 + tau_f. ``fail[0]`` = 1 + index of a failed point (0 if none).
    With swirl (Lw, spw (N, 2), else (0, 2)): spw = (r theta, theta z) of sigma~ + tau_f.
    Work arrays of each lane t: S[t] (NSTRESS, BLOCK), W[t] (NWORK, BLOCK), blk[t] (3, BLOCK)
    (phi, pore pressure, fluid viscosity); ``none``: an empty (0, NOUT) array (no diagnostic
    outputs).
    """
    sw = Lw.shape[0] > 0
    G, K = P[16], P[17]
    N = vol.shape[0]
    lanes = S.shape[0]
    nblocks = (N + BLOCK - 1) // BLOCK
    for t in nb.prange(lanes):
        Sc, Wc, phib, prb, etab = S[t], W[t], blk[t, 0], blk[t, 1], blk[t, 2]
        for jb in range(t, nblocks, lanes):
            lo = jb * BLOCK
            hi = min(lo + BLOCK, N)
            n = hi - lo
            for k in range(n):
                p = lo + k
                phib[k] = svol[p] / vol[p]
                _trial(stress, L, Lw, p, dt, G, K, Sc, k)
                vol[p] *= _jacobian(L, p, dt)
            # gdot: the warm start of a jammed point's dilatant solve (its previous plastic
            # rate, checkpointed), then the new rate
            update_block(Sc, phib[:n], f[lo:hi], gdot[lo:hi], case[lo:hi], dt, P, Wc, none)
            if locked:      # pore pressure and fluid viscosity: loops over slices (SIMD)
                mc, sc, vc = m[lo:hi], svol[lo:hi], vol[lo:hi]
                for k in range(n):
                    prb[k] = laws.pore_pressure((mc[k] - rho_s * sc[k]) / (vc[k] - sc[k]),
                                                rho_f0, kappa)
                for k in range(n):
                    etab[k] = laws.fluid_viscosity(sc[k] / vc[k], eta0)
            for k in range(n):
                p = lo + k
                if case[p] == FAILED:
                    fail[0] = p + 1
                s00, s11, s22, s01 = Sc[0, k], Sc[1, k], Sc[2, k], Sc[3, k]
                stress[p, 0, 0], stress[p, 1, 1], stress[p, 2, 2] = s00, s11, s22
                stress[p, 0, 1] = stress[p, 1, 0] = s01
                pr = eta = 0.0
                txx = txy = tyy = ttt = 0.0
                if locked:
                    pr, eta = prb[k], etab[k]
                    txx, txy, tyy, ttt = _viscous(L, p, eta)
                if sw:
                    s02, s12 = Sc[4, k], Sc[5, k]
                    stress[p, 0, 2] = stress[p, 2, 0] = s02
                    stress[p, 1, 2] = stress[p, 2, 1] = s12
                    spw[p, 0] = s02 + eta * Lw[p, 0]
                    spw[p, 1] = s12 + eta * Lw[p, 1]
                pf[p] = pr
                sp[p, 0] = s00 + txx - pr
                sp[p, 1] = s01 + txy
                sp[p, 2] = s11 + tyy - pr
                sp[p, 3] = s22 + ttt - pr


#: suspension_kernel's lanes per thread (blocks dealt round-robin to the lanes)
LANES_PER_THREAD = 4
_NO_SWIRL = np.zeros((0, 2))


def _swirl_arrays(ps):
    """(Lw, spw) of a set with swirl, else two empty (0, 2) arrays (the kernels skip them)."""
    if "Lw" in ps.arrays:
        return ps.arrays["Lw"], ps.arrays["spw"]
    return _NO_SWIRL, _NO_SWIRL


def elastic_energy(stress, vol, G, K) -> float:
    """Stored linear-elastic energy sum V (s:s/(4G) + p^2/(2K)) of stresses (N, 3, 3) [J]."""
    taubar, p = invariants(stress)
    return float(np.sum(vol * (taubar ** 2 / (2.0 * G) + p * p / (2.0 * K))))


# ------------------------------------------------------------------ material classes
class LinearElastic:
    """Linear isotropic elastic solid (Jaumann rate), e.g. disks, bars, a wheel, a skeleton.

    Parameters
    ----------
    rho : float
        True density [kg/m^3]; a point's mass is phi rho V (phi = 1 for a body).
    K, G : float
        Bulk and shear moduli [Pa]; or give ``E`` [Pa] and ``nu`` [-] instead.
    """

    phase = "solid"
    name = "elastic"
    default_phi = 1.0

    def __init__(self, rho, K=None, G=None, *, E=None, nu=None):
        self.rho = float(check_positive("rho", rho))
        if E is not None or nu is not None:
            if K is not None or G is not None:
                raise ValueError("give either (K, G) or (E, nu), not both")
            E = float(check_positive("E", E))
            nu = float(check_range("nu", nu, -1.0, 0.5, lo_closed=False, hi_closed=False))
            K, G = E / (3.0 * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))
        if K is None or G is None:
            raise ValueError("LinearElastic needs K and G [Pa] (or E and nu)")
        self.K = float(check_positive("K", K))
        self.G = float(check_positive("G", G))

    def describe(self) -> str:
        return f"linear elastic (K = {self.K:g} Pa, G = {self.G:g} Pa, rho = {self.rho:g} kg/m^3)"

    def initialise(self, ps, phi, **state):
        if state:
            raise ValueError(f"{ps.name}: unknown state {sorted(state)} for a linear elastic "
                             "material")
        check_range(f"{ps.name}: phi", phi, 0.0, 1.0, lo_closed=False)
        ps.arrays["svol"] = phi * ps.V
        ps.arrays["m"] = self.rho * ps.svol
        s = ps.stress
        ps.sp[:] = np.stack([s[:, 0, 0], s[:, 0, 1], s[:, 1, 1], s[:, 2, 2]], axis=1)

    def update(self, ps, dt, chunks, parallel, **_):
        elastic_kernel[parallel](ps.stress, ps.L, ps.V, dt, self.G, self.K, ps.sp,
                                 *_swirl_arrays(ps))

    def g2p_update(self, ps, g2p_args, dt, chunks, parallel):
        """G2P of the set fused with :meth:`update` (one pass, identical results):
        ``g2p_args`` are :func:`mpm2d.transfer.g2p`'s arguments (ps.x ... flag)."""
        elastic_g2p_kernel[parallel](*g2p_args, ps.stress, ps.V, self.G, self.K, ps.sp,
                                     *_swirl_arrays(ps))

    def wave_modulus(self) -> float:
        """Modulus S of the fastest wave, c^2 = S V/m [Pa] (P wave, K + 4G/3)."""
        return self.K + 4.0 * self.G / 3.0

    def viscosity_bound(self) -> float:
        return 0.0

    def strain_energy(self, ps) -> float:
        """Stored elastic energy [J] (per unit thickness, or per radian)."""
        return elastic_energy(ps.stress, ps.V, self.G, self.K)

    def output_fields(self, ps) -> dict:
        return {"pressure_Pa": -np.trace(ps.stress, axis1=1, axis2=2) / 3.0}


class NewtonianFluid:
    """Weakly compressible Newtonian fluid (Table 8 fluid phase, or a plain fluid).

    Parameters
    ----------
    eta0 : float
        Viscosity [Pa s]; with ``einstein`` the fluid phase of a mixture has eta0 (1 + 5/2 phi).
    rho : float
        Reference true density rho_0f [kg/m^3] (p_f = 0).
    kappa : float
        Bulk modulus [Pa], p_f = kappa ln(rho_f/rho_0f).
    einstein : bool
        Apply the Einstein correction with the local volume fraction of grains (two phases).
    """

    phase = "fluid"
    name = "newtonian"
    default_phi = 0.0

    def __init__(self, eta0, rho, kappa, einstein=True):
        self.eta0 = float(check_positive("eta0", eta0))
        self.rho = float(check_positive("rho", rho))
        self.kappa = float(check_positive("kappa", kappa))
        self.einstein = bool(einstein)

    @classmethod
    def from_material(cls, m: Material) -> "NewtonianFluid":
        """The fluid phase of a rheology parameter set (eta0, rho_f, kappa)."""
        m.require("rho_f", "kappa")
        return cls(m.eta0, m.rho_f, m.kappa)

    def describe(self) -> str:
        return (f"Newtonian fluid (eta0 = {self.eta0:g} Pa s, rho = {self.rho:g} kg/m^3, "
                f"kappa = {self.kappa:g} Pa)")

    def initialise(self, ps, phi, rho_f=None, **state):
        if state:
            raise ValueError(f"{ps.name}: unknown state {sorted(state)} for a Newtonian fluid")
        check_range(f"{ps.name}: phi", phi, 0.0, 1.0, hi_closed=False,
                    note="fraction of grains around the fluid points")
        rho_f = np.full(len(ps), self.rho) if rho_f is None else np.array(
            np.broadcast_to(check_positive(f"{ps.name}: rho_f", rho_f), (len(ps),)))
        ps.arrays["n"] = 1.0 - phi
        ps.arrays["rho_f"] = rho_f
        ps.arrays["m"] = ps.n * rho_f * ps.V
        ps.arrays["svol"] = np.zeros(len(ps))
        ps.arrays["divq"] = np.zeros(len(ps))
        pr = laws.pore_pressure(rho_f, self.rho, self.kappa)
        ps.arrays["pf"] = pr
        ps.stress[:] = -pr[:, None, None] * np.eye(3)
        ps.sp[:] = np.stack([-pr, 0 * pr, -pr, -pr], axis=1)

    def update(self, ps, dt, chunks, parallel, two_phase=False, **_):
        fluid_kernel[parallel](ps.L, ps.V, ps.m, ps.rho_f, ps.divq, ps.n, dt, self.eta0,
                     self.einstein, self.rho, self.kappa, two_phase, ps.sp, ps.pf,
                     *_swirl_arrays(ps))
        self.two_phase = two_phase

    def wave_modulus(self) -> float:
        """c^2 = kappa V/m = kappa/(n rho_f) (the pore pressure acts on the fluid's n rho_f)."""
        return self.kappa

    def viscosity_bound(self) -> float:
        return laws.fluid_viscosity(1.0 if self.einstein else 0.0, self.eta0)    # phi <= 1

    def strain_energy(self, ps) -> float:
        """Stored compression energy sum V kappa (rho ln(rho/rho0) - rho + rho0)/rho [J]."""
        r = ps.rho_f / self.rho
        return float(np.sum(ps.V * self.kappa * (np.log(r) - 1.0 + 1.0 / r)))

    def output_fields(self, ps) -> dict:
        """Pore pressure, density, grain fraction and the full stress tau_f - p_f 1."""
        sp = ps.sp
        pr = ps.pf if getattr(self, "two_phase", False) else np.zeros(len(ps))
        s = np.zeros((len(ps), 3, 3))
        s[:, 0, 0], s[:, 1, 1], s[:, 2, 2] = sp[:, 0] - pr, sp[:, 2] - pr, sp[:, 3] - pr
        s[:, 0, 1] = s[:, 1, 0] = sp[:, 1]
        return {"pore_pressure_Pa": ps.pf.copy(), "rho_f": ps.rho_f.copy(), "phi": 1.0 - ps.n,
                "stress": s}


class Suspension:
    """The Table 8 dense-suspension law (granular phase, or the locked mixture).

    Parameters
    ----------
    material : rheology.Material
        Needs G, K, K0, rho_s (and rho_f, kappa when ``locked``).
    locked : bool
        Locked mixture: one velocity field, the points carry grains and fluid (mass
        (phi rho_s + (1 - phi) rho_f) V, stress sigma~ - p_f 1 + tau_f). Otherwise the granular
        phase of a two-phase run (mass phi rho_s V, stress sigma~).
    """

    phase = "solid"
    default_phi = None

    def __init__(self, material: Material, locked: bool = False):
        self.m = material
        self.P = kernel_parameters(material)
        material.require("rho_s")
        self.locked = bool(locked)
        if self.locked:
            material.require("rho_f", "kappa")
        self.name = "suspension (locked mixture)" if locked else "suspension (granular phase)"

    def describe(self) -> str:
        return f"{self.name}: Table 8 law, parameter set {self.m.name}"

    def initialise(self, ps, phi, f=0.0, pf=0.0, **state):
        """Masses and state; ``f`` the initial structure, ``pf`` [Pa] the initial pore pressure
        of a locked mixture (its fluid then starts at rho_f0 exp(pf/kappa))."""
        if state:
            raise ValueError(f"{ps.name}: unknown state {sorted(state)} for the suspension law")
        m = self.m
        check_range(f"{ps.name}: phi", phi, 0.0, 1.0, lo_closed=False, hi_closed=False)
        ps.arrays["svol"] = phi * ps.V
        pf = np.broadcast_to(check_range(f"{ps.name}: pf", pf), (len(ps),))
        if np.any(pf != 0.0) and not self.locked:
            raise ValueError(f"{ps.name}: pf is the pore pressure of a locked mixture; in "
                             "two-phase runs give the fluid points rho_f")
        rho_f = m.rho_f * np.exp(pf / m.kappa) if self.locked else 0.0
        ps.arrays["m"] = (phi * m.rho_s + (1.0 - phi) * rho_f) * ps.V
        ps.arrays["f"] = check_range(f"{ps.name}: f", np.broadcast_to(np.asarray(f, float),
                                                                      (len(ps),)), 0.0, 1.0).copy()
        for k in ("gdot_p", "case"):
            ps.arrays[k] = np.zeros(len(ps))
        ps.arrays["pf"] = np.array(pf, dtype=float)
        s = ps.stress
        ps.sp[:] = np.stack([s[:, 0, 0], s[:, 0, 1], s[:, 1, 1], s[:, 2, 2]], axis=1)
        ps.sp[:, [0, 2, 3]] -= ps.pf[:, None]

    def update(self, ps, dt, chunks, parallel, **_):
        m = self.m
        fail = np.zeros(1, dtype=np.int64)
        suspension_kernel[parallel](ps.stress, ps.L, ps.V, ps.svol, ps.m, ps.f, dt, self.P,
                                    self.locked, m.rho_s, m.rho_f if self.locked else 1.0,
                                    m.kappa if self.locked else 0.0, m.eta0, ps.sp, ps.pf,
                                    ps.gdot_p, ps.case, fail, *_swirl_arrays(ps),
                                    *self._work(LANES_PER_THREAD * nb.get_num_threads()
                                                if parallel else 1))
        if fail[0]:
            k = fail[0] - 1
            raise RuntimeError(f"{ps.name}: the Table 8 local update failed at point id "
                               f"{ps.id[k]} (x = {ps.x[k].tolist()}, phi = "
                               f"{ps.svol[k] / ps.V[k]:.6g}, f = {ps.f[k]:.6g}, stress = "
                               f"{ps.stress[k].round(6).tolist()}, dt = {dt:g} s)")

    def _work(self, lanes):
        """suspension_kernel's work arrays for ``lanes`` lanes (kept between steps)."""
        w = self.__dict__.get("_work_arrays")
        if w is None or w[0].shape[0] != lanes:
            w = (np.zeros((lanes, NSTRESS, BLOCK)), np.zeros((lanes, NWORK, BLOCK)),
                 np.zeros((lanes, 3, BLOCK)), np.zeros((0, NOUT)))
            self._work_arrays = w
        return w

    def wave_modulus(self) -> float:
        m = self.m
        s = m.K + 4.0 * m.G / 3.0
        if self.locked:
            s += m.kappa / (1.0 - m.phi_j)
        return s

    def viscosity_bound(self) -> float:
        return laws.fluid_viscosity(self.m.phi_j, self.m.eta0) if self.locked else 0.0

    def strain_energy(self, ps) -> float:
        """Elastic energy stored in the skeleton [J]."""
        return elastic_energy(ps.stress, ps.V, self.m.G, self.m.K)

    def output_fields(self, ps) -> dict:
        taubar, p = invariants(ps.stress)
        out = {"phi": ps.svol / ps.V, "f": ps.f.copy(), "granular_pressure_Pa": p,
               "taubar_Pa": taubar,
               "shear_rate_p_per_s": ps.gdot_p.copy(), "case": ps.case.copy()}
        if self.locked:
            out["pore_pressure_Pa"] = ps.pf.copy()
        return out
