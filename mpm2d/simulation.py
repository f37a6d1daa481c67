"""The explicit MPM step: particle-to-grid, grid update, grid-to-particle, constitutive update.

One step of size dt (USL: the stress is updated last, from the new grid velocities)::

    1. P2G           mass, APIC momentum, internal + external force (and, with two phases,
                     volumes and the pore-pressure force) into private node fields, reduced
    2. grid update   gravity; mirror/periodic boundaries (fold); axisymmetry: the wall/axis
                     correction (_axis_correction); two phases: nodal phi, buoyancy split,
                     v* = (p + dt f)/m, implicit drag; contact (mpm2d.contact: deformable
                     bodies on their own fields, then rigid bodies, implicitly); ghost nodes
                     (unfold)
    3. G2P           v, C (APIC) or FLIP/PIC blend, L = grad v, x += dt v; a linear-elastic
                     set's stress update (phase 4) is done in the same pass, point by point
    4. constitutive  each set's material advances stress, volume and state with L
    5. bodies move; t += dt; every ``sort_every`` steps the points are re-sorted by B-spline
       base node (O(N) counting sort, skipped when already in order)

Modes (stated in every run's log and manifest):

- ``single phase``: one velocity field; elastic bodies, a Newtonian fluid, or the suspension
  law's granular phase alone;
- ``two-phase``: granular and fluid points on two velocity fields coupled at the nodes by
  implicit drag and buoyancy (Table 8);
- ``locked mixture``: one velocity field; suspension points carry grains and fluid with the
  undrained pore pressure (for scenes whose phases cannot separate on the time scale of
  interest: drag time ~1e-5 s for d = 5.85 um).

Step size: dt = min(cfl h/c_max, cfl h/|v|_max, cfl_visc rho h^2/eta_max) with c^2 = S V/m the
fastest wave of each set (S = K + 4G/3 for solids, kappa for fluid points, K + 4G/3 + kappa/n for
the locked mixture; m/V is the phase's partial density, so the granular phase at phi uses
phi rho_s). A user dt above the limit is refused.
"""

from __future__ import annotations

import math
import time

import numba as nb
import numpy as np

from runkit.params import check_positive, check_range

from . import grid_update as gu
from .kernels import PARALLEL_MIN_POINTS, dual
from .grid import (FPX, FX, M, V, NF_ONE, NF_TWO, NOSLIP, PAD, SLIP, SIDES, Grid, fold,
                   fold_swirl, unfold, unfold_swirl)
from .materials import Suspension
from .particles import ParticleSet
from .bodies import check_mu
from . import contact as ct
from .transfer import (boundary_velocities, wall_moments, chunk_bounds, g2p, g2p_swirl,
                       gather_scalar_vector, p2g, p2g_swirl, reduce_private, reduce_velocities,
                       sort_order)

_EMPTY = np.zeros(0)
MODES = ("single phase", "two-phase", "locked mixture")
TRANSFERS = ("apic", "flip", "pic")


@dual
def _extremes(m, vol, v, chunks, out):
    """Per chunk into out (nc, 2): max V/m [m^3/kg] and max |v|^2 [m^2/s^2]."""
    nc = chunks.shape[0] - 1
    for c in nb.prange(nc):
        a = b = 0.0
        for p in range(chunks[c], chunks[c + 1]):
            a = max(a, vol[p] / m[p])
            b = max(b, v[p, 0] * v[p, 0] + v[p, 1] * v[p, 1])
        out[c, 0], out[c, 1] = a, b
    return out


class Drag:
    """Parameters of the inter-phase drag C = 18 phi (1 - phi) eta0 F(phi, Re)/d^2.

    Parameters
    ----------
    eta0 : float  fluid viscosity [Pa s]
    d : float     grain diameter [m]
    rho_f : float fluid density for the Reynolds number [kg/m^3]
    """

    def __init__(self, eta0, d, rho_f):
        self.eta0 = float(check_positive("eta0", eta0))
        self.d = float(check_positive("d", d, note="the drag needs a grain diameter"))
        self.rho_f = float(check_positive("rho_f", rho_f))

    @classmethod
    def from_material(cls, m):
        m.require("rho_f")
        return cls(m.eta0, m.d, m.rho_f)


class Simulation:
    """An MPM model: grid, particle sets, rigid bodies and the step.

    Parameters
    ----------
    grid : Grid
    sets : list of ParticleSet
    bodies : list of RigidBody
    mode : str, optional
        ``single phase``, ``two-phase`` or ``locked mixture``; inferred if omitted.
    gravity : (2,) [m/s^2]
    transfer : ``apic`` (default), ``flip`` or ``pic``; ``flip_alpha`` is the FLIP fraction
        of the FLIP/PIC blend (``flip`` only; ``pic`` is alpha = 0).
    dt : float, optional
        Fixed step [s]; refused if above the stability limit. Default: adaptive.
    cfl, cfl_visc : safety factors of the wave/advection and viscous limits.
    drag : Drag, required in two-phase mode (default: from a suspension set's material).
    sort_every : re-sort points by base node every this many steps (cache locality, P2G runs).
    chunks : number of private P2G grids (default: numba's thread count); results are
        bit-identical for any thread count at a fixed ``chunks``.
    contact_sets : dict, optional
        ``{set name: mu_w}``: deformable bodies (e.g. an elastic wheel) on their own velocity
        field, in contact with the material's fields with Coulomb friction mu_w (0 to ``inf``)
        instead of sharing its velocity (see :mod:`mpm2d.contact`).
    swirl : bool
        Axisymmetric runs only: carry the azimuthal velocity v_theta (every set gets
        ``vtheta``, see :meth:`ParticleSet.enable_swirl`), with the stresses sigma_r_theta,
        sigma_theta_z and the Jaumann terms through the 3 x 3 L of the law, the angular-momentum
        balance rho D(r v_theta)/Dt = (1/r) d(r^2 sigma_r_theta)/dr + r d(sigma_theta_z)/dz and
        the centrifugal force rho v_theta^2/r in the radial balance; cylindrical walls turn at
        ``grid.wall_swirl`` (ramped linearly over ``swirl_ramp`` [s] if > 0). Single-phase and
        locked-mixture modes, no rigid bodies or contact sets (refused otherwise). Off
        (default): the step is exactly the one without swirl.
    swirl_flip : float in [0, 1)
        FLIP fraction of the swirl transfer with APIC (the APIC-FLIP blend of Fei et al. 2021,
        :func:`mpm2d.transfer.g2p_swirl`): 0 (default) is plain APIC, which damps a shear wave
        once per step (at fixed h more the smaller dt: a torsional elastic wave of 8 cells per
        wavelength lost 14 % of its energy in four periods at cfl 0.5, 36 % at cfl 0.125); 0.99
        keeps 99 % of what the point carries beyond the grid's interpolant (energy kept to 1 %
        at both). With ``transfer="flip"`` the swirl uses ``flip_alpha``, with PIC none.
    """

    def __init__(self, grid: Grid, sets, bodies=(), *, mode=None, gravity=(0.0, 0.0),
                 transfer="apic", flip_alpha=0.99, dt=None, cfl=0.5, cfl_visc=0.25, drag=None,
                 sort_every=20, chunks=None, name="mpm2d", contact_sets=None, swirl=False,
                 swirl_ramp=0.0, swirl_flip=0.0):
        self.grid, self.sets, self.bodies, self.name = grid, list(sets), list(bodies), name
        if not self.sets:
            raise ValueError("a simulation needs at least one particle set")
        names = [s.name for s in self.sets] + [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ValueError(f"particle set and body names must be unique, got {names}")
        for s in self.sets:
            if s.axisymmetric != grid.axisymmetric:
                raise ValueError(f"set {s.name}: axisymmetric = {s.axisymmetric} but the grid "
                                 f"is {'axisymmetric' if grid.axisymmetric else 'plane'}")
        transfer = str(transfer).lower()
        if transfer not in TRANSFERS:
            raise ValueError(f"transfer = {transfer!r} must be one of {TRANSFERS}")
        self.transfer = transfer
        self.flip_alpha = 0.0 if transfer == "pic" else float(
            check_range("flip_alpha", flip_alpha, 0.0, 1.0))
        self.gravity = np.asarray(gravity, dtype=float).reshape(2)
        check_range("gravity", self.gravity)
        self.cfl = float(check_range("cfl", cfl, 0.0, 1.0, lo_closed=False))
        self.cfl_visc = float(check_range("cfl_visc", cfl_visc, 0.0, 0.5, lo_closed=False))
        self.sort_every = int(sort_every)
        self.mode = self._infer_mode(mode)
        self.two_phase = self.mode == "two-phase"
        if self.two_phase:
            if drag is None:
                susp = [s.material.m for s in self.sets if isinstance(s.material, Suspension)]
                if not susp:
                    raise ValueError("two-phase mode needs drag=Drag(eta0, d, rho_f)")
                drag = Drag.from_material(susp[0])
            self.drag = drag
            for s in self.sets:
                if s.phase == "fluid":
                    s.material.two_phase = True
                    # the pore pressure acts through pf (FPX, shared by buoyancy): keep it out
                    # of the fluid's P2G stress at t = 0, as the fluid update does from step 1
                    # (a checkpoint's sp replaces this on resume)
                    s.sp[:, 0] = s.stress[:, 0, 0] + s.pf
                    s.sp[:, 2] = s.stress[:, 1, 1] + s.pf
                    s.sp[:, 3] = s.stress[:, 2, 2] + s.pf
        self.nc = int(chunks) if chunks else nb.get_num_threads()
        npts = sum(len(s) for s in self.sets)
        multi = nb.get_num_threads() > 1
        self.par = multi and npts >= PARALLEL_MIN_POINTS
        # a two-phase node does several times a single field's work (both phases' velocities,
        # the nodal phi and the implicit Beetstra drag, with its powers): its grid loops pay for
        # their threads from a quarter of the nodes
        nodes = grid.shape[0] * grid.shape[1] * (4 if self.two_phase else 1)
        self.par_grid = multi and nodes >= PARALLEL_MIN_POINTS
        nf = NF_TWO if self.two_phase else NF_ONE
        shape = grid.shape
        self.phases = ("solid", "fluid") if self.two_phase else ("solid",)
        self.contact_sets = {}
        set_names = {s.name: s for s in self.sets}
        for k, mu in dict(contact_sets or {}).items():
            if k not in set_names:
                raise ValueError(f"contact_sets: no particle set named {k!r} (sets: "
                                 f"{sorted(set_names)})")
            if set_names[k].phase != "solid" or isinstance(set_names[k].material, Suspension):
                raise ValueError(f"contact_sets: set {k!r} must be a solid body (elastic), not "
                                 f"{set_names[k].material.name}")
            self.contact_sets[k] = check_mu(f"contact_sets[{k}]", mu)
        for b in self.bodies:
            bad = set(b.bonded_to) - set(set_names)
            if bad:
                raise ValueError(f"body {b.name}: bonded_to {sorted(bad)} names no particle set")
        #: every velocity field: the material's phases, then one per deformable body
        self.fields = self.phases + tuple(f"set:{k}" for k in self.contact_sets)
        nfs = {f: (nf if f in self.phases else NF_ONE) for f in self.fields}
        self.G = {ph: np.zeros(shape + (nfs[ph],)) for ph in self.fields}
        self.priv = {ph: np.zeros((self.nc,) + shape + (nfs[ph],)) for ph in self.fields}
        self.vg = {ph: np.zeros(shape + (2,)) for ph in self.fields}
        self.vg_old = {ph: np.zeros(shape + (2,)) for ph in self.fields}
        self._geo_work = np.zeros(shape + (NF_ONE,))
        self._wall_work = np.zeros(shape + (NF_TWO,))
        if self.two_phase:
            self.phi_nodes = np.zeros(shape)
            self.q_nodes = np.zeros(shape + (2,))
            self.drag_nodes = np.zeros(shape)
        self.node_x, self.node_y = grid.node_positions()
        self._geo = grid.geometry()
        self._flag = np.zeros(1, dtype=np.int64)
        self._chunks = {}
        #: per set, per chunk: max V/m and max |v|^2 as the last P2G scattered them
        self._ext = {s.name: np.zeros((self.nc, 2)) for s in self.sets}
        self.t, self.step_count, self.last_dt = 0.0, 0, 0.0
        #: force on each deformable contact body from the material in the last step [N]
        self.contact_force = {k: np.zeros(2) for k in self.contact_sets}
        #: accumulated wall time per phase of the step [s] (see :meth:`step`)
        self.timings = dict.fromkeys(("step size", "P2G", "grid update", "G2P", "constitutive",
                                      "sort"), 0.0)
        #: sets whose material updates in the G2P pass (g2p_update: linear elastic)
        self._fused_update = frozenset(s.name for s in self.sets
                                       if hasattr(s.material, "g2p_update"))
        self.swirl = bool(swirl)
        #: velocities in the reduction pass (transfer.reduce_velocities): only where nothing
        #: but the fold acts between the two (one velocity field, plane, no swirl)
        self._fuse_grid = not (self.two_phase or self.swirl or grid.axisymmetric)
        self._setup_swirl(float(check_range("swirl_ramp", swirl_ramp, 0.0, None)),
                          float(check_range("swirl_flip", swirl_flip, 0.0, 1.0, hi_closed=False)))
        self._sort()
        self.user_dt = None
        if dt is not None:
            dt = float(check_positive("dt", dt))
            limit = self.stable_dt()
            if dt > limit:
                raise ValueError(f"dt = {dt:.6g} s exceeds the stability limit {limit:.6g} s "
                                 f"({self._limit_reason}); use dt <= {limit:.3g} or omit dt")
            self.user_dt = dt

    # ------------------------------------------------------------------ set-up helpers
    def _setup_swirl(self, ramp, swirl_flip):
        g = self.grid
        if not self.swirl:
            if np.any(g.swirl_u != 0.0):
                raise ValueError("grid.wall_swirl turns a wall but swirl = False; use "
                                 "Simulation(..., swirl=True)")
            for s in self.sets:
                # without swirl the in-plane and hoop components are the whole stress (the
                # elastic update, rheology.local_update.jaumann_elastic_plane, carries no other)
                shear = np.abs(s.stress[:, [0, 1], 2]).max(initial=0.0)
                if shear > 0.0:
                    raise ValueError(f"set {s.name}: stress has out-of-plane shear components "
                                     f"(sigma_02, sigma_12 up to {shear:g} Pa); valid: 0 in a "
                                     "run without swirl (Simulation(swirl=True) carries them)")
            return
        if not g.axisymmetric:
            raise ValueError("swirl = True needs an axisymmetric grid (v_theta is the "
                             "out-of-plane velocity of an (r, z) run)")
        if self.two_phase:
            raise ValueError("swirl = True: two-phase mode is not supported (single phase or "
                             "locked mixture)")
        if self.bodies or self.contact_sets:
            raise ValueError("swirl = True: rigid bodies and contact sets are not supported "
                             "(drive v_theta with grid.wall_swirl)")
        for s in self.sets:
            s.enable_swirl()
        self.swirl_ramp = ramp
        # FLIP fraction of the swirl transfer (g2p_swirl): flip_alpha with FLIP, swirl_flip with
        # APIC (the APIC-FLIP blend), 0 with PIC
        self.swirl_alpha = (self.flip_alpha if self.transfer == "flip" else
                            swirl_flip if self.transfer == "apic" else 0.0)
        shape = self.grid.shape
        self.Gw = np.zeros(shape + (3,))
        self.privw = np.zeros((self.nc,) + shape + (3,))
        self.lg = np.zeros(shape)
        self.lg_old = np.zeros(shape)
        self._mw = np.zeros(shape)

    def swirl_wall_l(self, t) -> np.ndarray:
        """Wall values of l = r u_theta [m^2/s] per side at time t (ramped)."""
        g = self.grid
        ramp = min(1.0, t / self.swirl_ramp) if self.swirl_ramp > 0 else 1.0
        lw = np.zeros(4)
        lw[0] = g.origin[0] * g.swirl_u[0] * ramp
        lw[1] = g.upper[0] * g.swirl_u[1] * ramp
        return lw

    def _infer_mode(self, mode):
        has_fluid = any(s.phase == "fluid" for s in self.sets)
        locked = [isinstance(s.material, Suspension) and s.material.locked for s in self.sets]
        if mode is None:
            mode = ("two-phase" if has_fluid and any(s.phase == "solid" for s in self.sets)
                    else "locked mixture" if any(locked) else "single phase")
        if mode not in MODES:
            raise ValueError(f"mode = {mode!r} must be one of {MODES}")
        if mode == "two-phase":
            if not has_fluid or not any(s.phase == "solid" for s in self.sets):
                raise ValueError("two-phase mode needs a granular (solid) set and a fluid set")
            if any(locked):
                raise ValueError("two-phase mode: suspension sets must have locked=False")
        elif any(locked) and mode != "locked mixture":
            raise ValueError(f"mode = {mode!r} but a suspension set is locked (use mode "
                             "'locked mixture')")
        elif mode == "locked mixture" and not any(locked):
            raise ValueError("mode 'locked mixture' needs a Suspension(..., locked=True) set")
        return mode

    def describe(self) -> str:
        lines = [f"{self.name}: mode {self.mode}; transfer {self.transfer}"
                 + (f" (FLIP fraction {self.flip_alpha})" if self.transfer == "flip" else "")
                 + f"; {self.grid.describe()}"]
        for s in self.sets:
            own = (f"; own velocity field, contact mu_w = {self.contact_sets[s.name]:g}"
                   if s.name in self.contact_sets else "")
            lines.append(f"  set {s.name}: {len(s)} points, {s.material.describe()}{own}")
        extent = " per radian" if self.grid.axisymmetric else " per m of thickness"
        for b in self.bodies:
            lines.append(f"  {b.describe(extent)}")
        lines.append(f"  gravity ({self.gravity[0]:g}, {self.gravity[1]:g}) m/s^2; dt "
                     + (f"{self.user_dt:g} s (fixed)" if self.user_dt else
                        f"adaptive, cfl {self.cfl}, now {self.stable_dt():.4g} s "
                        f"({self._limit_reason})"))
        return "\n".join(lines)

    def _field(self, s: ParticleSet) -> str:
        if s.name in self.contact_sets:
            return f"set:{s.name}"
        return "fluid" if (self.two_phase and s.phase == "fluid") else "solid"

    def _sort(self):
        """Order every set's points by B-spline base node (row-major): chunks are compact
        regions and consecutive points share their 3 x 3 stencil (see transfer.p2g)."""
        for s in self.sets:
            order = sort_order(s.x, self._geo, self.grid.shape[1] + 4)
            if order.size:
                s.permute(order)
            self._chunks[s.name] = chunk_bounds(len(s), self.nc)

    # ------------------------------------------------------------------ step size
    def stable_dt(self, _ext=None) -> float:
        """The largest stable step now [s] (sets ``_limit_reason``).

        ``_ext`` (internal): {set name: (nc, 2) per-chunk max V/m, max |v|^2} already taken from
        the current state (by the step's P2G pass, :func:`mpm2d.transfer.p2g`); else computed."""
        h = self.grid.h
        c2 = v2 = nu = 0.0
        for s in self.sets:
            e = _ext[s.name] if _ext is not None else np.zeros((self.nc, 2))
            if _ext is None:
                _extremes[self.par](s.m, s.V, s.v, self._chunks[s.name], e)
            ext = e.max(axis=0)
            c2 = max(c2, s.material.wave_modulus() * ext[0])
            nu = max(nu, s.material.viscosity_bound() * ext[0])
            v2 = max(v2, ext[1])
        for b in self.bodies:
            reach = np.sqrt((b.offset ** 2).sum(axis=1).max())
            v2 = max(v2, float(b.velocity @ b.velocity) + (b.omega * reach) ** 2)
        limits = {"elastic/acoustic wave": self.cfl * h / math.sqrt(c2) if c2 > 0 else math.inf,
                  "advection": self.cfl * h / math.sqrt(v2) if v2 > 0 else math.inf,
                  "viscous diffusion": self.cfl_visc * h * h / nu if nu > 0 else math.inf}
        self._limit_reason = min(limits, key=limits.get)
        dt = limits[self._limit_reason]
        if not math.isfinite(dt):
            raise ValueError("no finite stable step: the model has no stiffness, viscosity or "
                             "motion; give dt")
        self._limit_reason += f" limit, cfl {self.cfl}" if "viscous" not in self._limit_reason \
            else f" limit, cfl_visc {self.cfl_visc}"
        return dt

    def _step_size(self, _ext=None) -> float:
        limit = self.stable_dt(_ext)
        if self.user_dt is None:
            return limit
        if self.user_dt > limit * (1.0 + 1e-12):
            raise RuntimeError(f"dt = {self.user_dt:.6g} s now exceeds the stability limit "
                               f"{limit:.6g} s ({self._limit_reason}) at t = {self.t:.6g} s, "
                               f"step {self.step_count}")
        return self.user_dt

    # ------------------------------------------------------------------ the step
    def step(self, dt: float | None = None) -> float:
        """Advance one step (dt: override, for tests); returns the dt used [s]."""
        clock = time.perf_counter
        t0 = clock()
        self._scatter()
        t1 = clock()
        # the step size from the extremes P2G took of the state it scattered (one pass fewer)
        dt = self._step_size(self._ext) if dt is None else dt
        t2 = clock()
        fused = self._fuse_grid
        self._reduce(dt if fused else None)
        t2b = clock()
        self._grid_update(dt, velocities_done=fused)
        t3 = clock()
        self._g2p(dt)
        t4 = clock()
        self._constitutive_update(dt)
        t5 = clock()
        for b in self.bodies:
            b.advance(dt)
        tm = self.timings
        tm["P2G"] += (t1 - t0) + (t2b - t2)
        tm["step size"] += t2 - t1
        tm["grid update"] += t3 - t2b
        tm["G2P"] += t4 - t3
        tm["constitutive"] += t5 - t4
        self.t += dt
        self.step_count += 1
        self.last_dt = dt
        if self.sort_every and self.step_count % self.sort_every == 0:
            t6 = clock()
            self._sort()
            tm["sort"] += clock() - t6
        return dt

    def _p2g(self):
        """Phase 1: particles to private node fields, reduced per phase with the body force
        m_i g; records each set's extremes for the step size in ``_ext``."""
        self._scatter()
        self._reduce()

    def _scatter(self):
        """Phase 1a: every set's P2G into the private node fields (and its extremes)."""
        axi = self.grid.axisymmetric
        for s in self.sets:
            ph = self._field(s)
            svol = s.svol if (self.two_phase and ph in self.phases) else _EMPTY
            pf = s.pf if (self.two_phase and s.phase == "fluid") else _EMPTY
            p2g[self.par](s.x, s.v, s.C, s.m, s.V, s.sp, pf, s.fext, svol, self._geo, axi,
                self._chunks[s.name], self.priv[ph], self._ext[s.name], self.gravity)
        if self.swirl:
            for s in self.sets:
                p2g_swirl[self.par](s.x, s.m, s.V, s.vtheta, s.Cl, s.spw, self._geo,
                                    self._chunks[s.name], self.privw)

    def _reduce(self, dt=None):
        """Phase 1b: the private fields summed per phase with the body force m_i g; with
        ``dt`` (only when ``_fuse_grid``) also the nodal velocities in the same pass, the
        boundary nodes' then redone after the fold (:meth:`_grid_update`)."""
        gx, gy = self.gravity[0], self.gravity[1]
        for ph in self.fields:
            if dt is None:
                reduce_private[self.par_grid](self.priv[ph], self.G[ph], True, gx, gy)
            else:
                reduce_velocities[self.par_grid](self.priv[ph], self.G[ph], gx, gy, dt,
                                                 self.vg[ph], self.vg_old[ph],
                                                 self.transfer != "apic")
        if self.swirl:
            reduce_private[self.par_grid](self.privw, self.Gw, False, 0.0, 0.0)
            G = self.G["solid"]
            G[:, :, FX] += self.Gw[:, :, 2]

    def _grid_update(self, dt, velocities_done=False):
        """Phase 2: boundaries, velocities, drag, bodies, ghost nodes (the body force came
        with the P2G reduction; with ``velocities_done`` the velocities too, from
        :meth:`_reduce` with dt, and only the nodes the fold changed are redone here)."""
        g, kind, wall_u = self.grid, self.grid.kind, self.grid.wall_u
        pg = self.par_grid
        if self.swirl:
            # fold the angular momentum and torque first, with the unfolded masses (the image
            # momentum about a turning wall needs the images' mass)
            self._mw[:] = self.G["solid"][:, :, M]
            fold_swirl(self.Gw, self._mw, g.kind, self.swirl_wall_l(self.t + dt),
                       g.nx, g.ny, g.on_axis)
        for ph in self.fields:
            fold(self.G[ph], kind, wall_u, g.nx, g.ny)
        if self.swirl:
            self._swirl_update(dt)
        if g.axisymmetric:
            self._axis_correction()
        if self.two_phase:
            # nodal phi, buoyancy split, both phases' velocities and the implicit drag in one
            # pass (grid_update.two_phase_nodes)
            Gs, Gf = self.G["solid"], self.G["fluid"]
            d = self.drag
            gu.two_phase_nodes[pg](Gs, Gf, self.phi_nodes, dt, self.vg["solid"],
                                   self.vg_old["solid"], self.vg["fluid"], self.vg_old["fluid"],
                                   d.eta0, d.d, d.rho_f, self.drag_nodes)
        for ph in self.fields:
            if velocities_done:
                boundary_velocities(self.G[ph], dt, self.vg[ph], self.vg_old[ph],
                                    self.transfer != "apic")
            elif not (self.two_phase and ph in self.phases):
                gu.velocities[pg](self.G[ph], dt, self.vg[ph], self.vg_old[ph])
        self._contact(dt)
        for ph in self.fields:
            unfold(self.vg[ph], kind, wall_u, g.nx, g.ny, True)
            if self.transfer != "apic":
                unfold(self.vg_old[ph], kind, wall_u, g.nx, g.ny, True)
        if self.two_phase:
            gu.mixture_flux[pg](Gs, Gf, self.phi_nodes, self.vg["solid"], self.vg["fluid"],
                            self.q_nodes)
            unfold(self.q_nodes, kind, wall_u, g.nx, g.ny, True)
            unfold(self.phi_nodes[:, :, None], kind, wall_u, g.nx, g.ny, False)

    def _swirl_update(self, dt):
        """Nodal l* = (sum N m l + dt torque)/m on the folded fields (folded in _p2g), the
        walls' l imposed on the wall nodes and the ghosts."""
        g = self.grid
        lw = self.swirl_wall_l(self.t + dt)
        mw, Gw, lg = self._mw, self.Gw, self.lg
        np.divide(Gw[:, :, 0] + dt * Gw[:, :, 1], mw, out=lg, where=mw > 0.0)
        lg[mw <= 0.0] = 0.0
        unfold_swirl(lg, g.kind, lw, g.nx, g.ny, g.on_axis)
        if self.swirl_alpha > 0.0:
            # the old nodal l (before the torque) of the FLIP part, same wall constraints
            lo = self.lg_old
            np.divide(Gw[:, :, 0], mw, out=lo, where=mw > 0.0)
            lo[mw <= 0.0] = 0.0
            unfold_swirl(lo, g.kind, lw, g.nx, g.ny, g.on_axis)

    # ------------------------------------------------------------------ axis
    def _axis_correction(self):
        """Make the radial nodal force of a radially uniform stress exactly zero at r-walls.

        Why: with the axis (and a wall r = R) as a mirror (odd radial test functions) the
        particle quadrature of int (r w_i)' dr = 0 is not exact at the nodes next to the mirror
        (the r weight is not symmetric about it): at r = h a uniform stress sigma_rr =
        sigma_thth = s leaves a radial force -s R with R = A_row/32 (two points per cell,
        quadratic B-splines), at the outer wall a force growing with the stress. A bed at rest
        (isotropic pore pressure and K_lat granular stress, uniform in r) is pushed off the
        axis; a material without shear stiffness (the locked mixture with its skeleton relaxed,
        a fluid) flows, and its pore pressure settled 4-10 % off in the axis cells. The
        correction adds s_bar_i R_i at the two node columns next to each mirror r-wall, with R_i
        the folded radial force of a unit uniform stress and s_bar_i the local mean of
        (sigma_rr + sigma_thth)/2 (of the pore pressure for the fluid's FPX): zero-order
        consistency of the discrete divergence (as in corrected SPH gradients); exact for
        uniform stress, an O(h) change for smooth fields. Plane strain needs none (its mirror
        quadrature is exact).
        """
        g = self.grid
        kind = g.kind
        band = 4.5 * g.h
        lo = band if kind[0] in (NOSLIP, SLIP) else 0.0
        hi = band if kind[1] in (NOSLIP, SLIP) else 0.0
        if lo == 0.0 and hi == 0.0:
            return
        cols = ([PAD + 1, PAD + 2] if lo else []) + ([PAD + g.nx - 1, PAD + g.nx - 2] if hi else [])
        zero_u = np.zeros((4, 2))
        for ph in self.fields:
            groups = [("sp", FX, 1.0)]
            if self.two_phase and ph == "fluid":
                groups.append(("pf", FPX, -1.0))
            for what, slot, sign in groups:
                mom = self._wall_work
                mom[:] = 0.0
                for s in self.sets:
                    if self._field(s) != ph:
                        continue
                    val = 0.5 * (s.sp[:, 0] + s.sp[:, 3]) if what == "sp" else s.pf
                    wall_moments(s.x, s.V, val, self._geo, lo, hi, mom)
                fold(mom, kind, zero_u, g.nx, g.ny)
                G = self.G[ph]
                for I in cols:
                    a = mom[I, :, M]
                    sbar = np.divide(mom[I, :, V], a, out=np.zeros_like(a), where=a > 0)
                    G[I, :, slot] += sign * sbar * mom[I, :, FX]

    # ------------------------------------------------------------------ contact
    def _points(self, field):
        """(x, side) of every set on a velocity field; side = sqrt(in-plane area) [m]."""
        out = []
        for s in self.sets:
            if self._field(s) == field:
                a = s.V / s.x[:, 0] if self.grid.axisymmetric else s.V
                out.append((s.x, np.sqrt(a)))
        return out

    def _field_geometry(self, field, cache):
        if field not in cache:
            pts = self._points(field)
            x = np.concatenate([p[0] for p in pts]) if pts else np.zeros((0, 2))
            side = np.concatenate([p[1] for p in pts]) if pts else np.zeros(0)
            cache[field] = ct.FieldGeometry(self.grid, x, side, self._geo_work)
        return cache[field]

    def _contact(self, dt):
        """Deformable-body and rigid-body contact on the predicted nodal velocities."""
        if not self.contact_sets and not self.bodies:
            return
        g = self.grid
        cache = {}
        for name, mu in self.contact_sets.items():
            fa = f"set:{name}"
            A = self._field_geometry(fa, cache)
            force = np.zeros(2)
            for ph in self.phases:
                B = self._field_geometry(ph, cache)
                both = (self.G[fa][:, :, M] > 0.0) & (self.G[ph][:, :, M] > 0.0)
                if not both.any():
                    continue
                n0 = ct.unit(A.outward - B.outward, np.array([0.0, 1.0]))
                touch, n = ct.touching(g, A.x, A.side, [(B.x, B.side)], n0, self._geo_work)
                gap = np.where(both & touch, -1.0, np.inf)
                ct.pair_contact(self.G[fa], self.G[ph], self.vg[fa], self.vg[ph], n, gap, 0.0,
                                mu, dt, force)
            self.contact_force[name] = force
        set_field = {s.name: self._field(s) for s in self.sets}
        for b in self.bodies:
            Bg = ct.FieldGeometry(g, b.x, b.side, self._geo_work)
            rx = self.node_x[:, None] - b.center[0]
            ry = self.node_y[None, :] - b.center[1]
            n0 = np.empty_like(Bg.outward)
            ct.rigid_normals(Bg.outward, self.node_x, self.node_y, b.center[0], b.center[1], n0)
            bonded = {set_field[k] for k in b.bonded_to}
            covered = Bg.area >= (0.5 - 1e-9) * g.h ** 2
            entries = []
            for ph in self.fields:
                Gm = self.G[ph][:, :, M]
                if ph in bonded:
                    nodes, n = covered & (Gm > 0.0), n0
                else:
                    mask = (Bg.area > 0.0) & (Gm > 0.0)
                    if not mask.any():
                        continue
                    touch, n = ((True, n0) if b.contact == "mass" else
                                ct.touching(g, Bg.x, Bg.side, self._points(ph), n0,
                                            self._geo_work))
                    nodes = mask & touch
                I, J = np.nonzero(nodes)
                if I.size == 0:
                    continue
                entries.append(dict(I=I, J=J, m=Gm[I, J], w=self.vg[ph][I, J].copy(),
                                    n=n[I, J], r=np.stack([rx[I, 0], ry[0, J]], axis=1),
                                    bonded=ph in bonded, vg=self.vg[ph]))
            ct.rigid_solve(b, entries, dt, self.gravity, g.h)

    def _g2p(self, dt):
        """Phase 3: velocities, affine matrices, gradients and positions of every set."""
        axi, kind = self.grid.axisymmetric, self.grid.kind
        apic = self.transfer == "apic"
        for s in self.sets:
            ph = self._field(s)
            if self.swirl:
                g2p_swirl[self.par](s.x, s.vtheta, s.Cl, s.Lw, self.lg, self.lg_old, self._geo,
                                    apic, self.swirl_alpha)
                r_old = s.x[:, 0].copy()
            args = (s.x, s.v, s.C, s.L, self.vg[ph], self.vg_old[ph], self._geo, axi, apic,
                    self.flip_alpha, dt, kind, self._flag)
            if s.name in self._fused_update:
                # the material's update in the same pass (phase 4 skips the set)
                s.material.g2p_update(s, args, dt, self._chunks[s.name], self.par)
            else:
                g2p[self.par](*args)
            if self.swirl:
                # l = r v_theta is what a point carries: v_theta at the new radius
                s.vtheta *= r_old / s.x[:, 0]
            if self._flag[0]:
                raise RuntimeError(f"set {s.name}: a point left the grid at t = {self.t:.6g} s "
                                   f"(step {self.step_count}); enlarge the grid or close the "
                                   "boundary")
            if self.two_phase and s.phase == "fluid":
                phi = np.empty(len(s))
                gather_scalar_vector[self.par](s.x, self.phi_nodes, self.q_nodes, self._geo, axi, phi,
                                     s.divq)
                np.subtract(1.0, phi, out=s.n)

    def _constitutive_update(self, dt):
        """Phase 4: each material advances its points with L over dt."""
        for s in self.sets:
            if s.name not in self._fused_update:
                s.material.update(s, dt, self._chunks[s.name], self.par,
                                  two_phase=self.two_phase)

    # ------------------------------------------------------------------ running
    def run(self, t_end: float, callback=None, every: int = 1, progress=None) -> None:
        """Step until ``t >= t_end`` [s]; ``callback(sim)`` every ``every`` steps."""
        while self.t < t_end * (1.0 - 1e-12):
            self.step()
            if callback is not None and self.step_count % every == 0:
                callback(self)
            if progress is not None:
                progress.update(self.t, self.step_count)

    # ------------------------------------------------------------------ diagnostics
    def energies(self) -> dict:
        """Kinetic, stored (strain/compression) and gravitational energy [J] (per unit
        thickness, or per radian)."""
        ke = sum(s.kinetic_energy() for s in self.sets) + sum(b.kinetic_energy()
                                                              for b in self.bodies)
        se = sum(s.material.strain_energy(s) for s in self.sets)
        pe = -sum(float(np.sum(s.m * (s.x @ self.gravity))) for s in self.sets)
        pe -= sum(b.mass * float(b.center @ self.gravity) for b in self.bodies)
        return {"kinetic_J": ke, "strain_J": se, "gravity_J": pe, "total_J": ke + se + pe}

    def momentum(self) -> np.ndarray:
        """Total linear momentum of points and bodies [kg m/s]."""
        p = sum(s.momentum() for s in self.sets)
        return p + sum((b.momentum() for b in self.bodies), np.zeros(2))

    def angular_momentum(self) -> float:
        """Total angular momentum about the origin, including APIC's affine part [kg m^2/s].

        For APIC the particle angular momentum is x_p x m_p v_p + m_p (D_p C_p^T) antisymmetric
        part: with D_p = h^2/4 I it is m_p h^2/4 (C_yx - C_xy).
        """
        h2 = self.grid.h ** 2 / 4.0
        L = 0.0
        for s in self.sets:
            L += float(np.sum(s.m * (s.x[:, 0] * s.v[:, 1] - s.x[:, 1] * s.v[:, 0])))
            if self.transfer == "apic":
                L += float(np.sum(s.m * h2 * (s.C[:, 1, 0] - s.C[:, 0, 1])))
        for b in self.bodies:
            L += b.mass * float(b.center[0] * b.velocity[1] - b.center[1] * b.velocity[0])
            L += b.inertia * b.omega
        return L

    def swirl_angular_momentum(self) -> float:
        """Total axial angular momentum of the swirl, sum m r v_theta (+ APIC part: l is
        carried affinely, its sum is sum m l_p) [kg m^2/s per radian]; 0 without swirl."""
        if not self.swirl:
            return 0.0
        return float(sum(np.sum(s.m * s.x[:, 0] * s.vtheta) for s in self.sets))

    # ------------------------------------------------------------------ checkpoints
    def state(self) -> dict:
        """Every array needed to continue bit-for-bit (see :meth:`load_state`)."""
        st = {"t": np.array(self.t), "step": np.array(self.step_count),
              "chunks": np.array(self.nc), "last_dt": np.array(self.last_dt)}
        for s in self.sets:
            for k, a in s.arrays.items():
                st[f"set.{s.name}.{k}"] = a
        for b in self.bodies:
            for k, a in b.state().items():
                st[f"body.{b.name}.{k}"] = a
        return st

    def load_state(self, st: dict) -> None:
        """Restore a state written by :meth:`state` into this (identically set-up) model."""
        if int(st["chunks"]) != self.nc:
            raise ValueError(f"checkpoint uses chunks = {int(st['chunks'])}, this model "
                             f"{self.nc}; set the same chunks to resume bit-for-bit")
        for s in self.sets:
            keys = [k for k in st if k.startswith(f"set.{s.name}.")]
            if not keys:
                raise ValueError(f"checkpoint has no particle set {s.name!r}")
            for k in keys:
                s.arrays[k.split(".", 2)[2]] = np.ascontiguousarray(st[k])
            self._chunks[s.name] = chunk_bounds(len(s), self.nc)
        for b in self.bodies:
            b.load_state({k.split(".", 2)[2]: v for k, v in st.items()
                          if k.startswith(f"body.{b.name}.")})
        self.t, self.step_count = float(st["t"]), int(st["step"])
        self.last_dt = float(st["last_dt"])
