"""The 1-D Couette problem: material, grid, drive, mode, and its method-of-lines right-hand side.

Equations (SI units; r the cross-gap coordinate, v the shear velocity, sigma the granular
effective stress, f the structure, phi the solid volume fraction):

- shear momentum of the mixture (the phases are locked in the shear direction by drag, whose
  relaxation time rho/C ~ 1e-7 s): ``rho dv/dt = r^-2 d(r^2 tau)/dr`` (annular) or
  ``rho dv/dt = d tau/dy`` (plane), ``tau = sigma_rth + eta0 (1 + 5/2 phi) gdot``,
  ``gdot = r d(v/r)/dr`` or ``dv/dy``; rho = phi rho_s + (1 - phi) rho_f;
- granular stress and structure: Table 8 in full, through :func:`rheology.local_update.update_point`
  (elastic-plastic, dilatant, with compaction and separation), in the co-rotating basis: stepped
  as it is by the explicit scheme, used as a rate (U_delta(state) - state)/delta by the method of
  lines (:meth:`Couette.rhs`, :meth:`Couette.rate_step_at`);
- ``mode="locked"``: the phases move together, phi is fixed (undrained), so shear dilatancy
  raises the granular pressure (dp/dt = K beta gdot_p) - the mechanism of dynamic shear jamming
  here;
- ``mode="two-phase"``: the solid also moves across the gap relative to the fluid by Darcy's law
  (Beetstra drag, pore pressure eliminated by the zero net flux of two incompressible phases between
  impermeable walls), which relieves the dilatancy pressure; phi obeys solid mass conservation.

No-slip walls (wall slip is a stated limitation, as in the paper). The moving wall (face 0: the
bob, or the moving plate) is driven at a speed or by a shear stress, ramped linearly over
``ramp_time``; the other wall is at rest.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rheology import granular_viscosity, kernel_parameters
from rheology.elastic import ELASTIC_STRAIN_LIMIT
from rheology.materials import Material
from runkit.limits import (GRAIN_MAX, GRAIN_MIN, LENGTH_MAX, PHI_MIN, SPEED_MAX, SPEED_MIN,
                           STRESS_MAX, STRESS_MIN, TIME_MAX, TIME_MIN, Bound)
from runkit.params import OutOfRange, Param, interval_text, shown

from . import kernels
from .geometry import CELL_MIN_GRAINS, R_INNER_MIN_GRAINS, Grid, min_gap

MODES = ("locked", "two-phase")
#: The start-up ramp of the drive [s]: a duration (runkit.limits), or 0, an impulsive start.
RAMP_TIME = Param(TIME_MIN, TIME_MAX, unit="s", also=(0.0,))


def max_wall_speed(material, phi0: float) -> float:
    """Largest wall speed [m/s] the model is used at: ELASTIC_STRAIN_LIMIT c_s, c_s =
    sqrt(G/rho) with rho = phi0 rho_s + (1 - phi0) rho_f (see :func:`drive_limit`)."""
    rho = phi0 * material.rho_s + (1.0 - phi0) * material.rho_f
    return ELASTIC_STRAIN_LIMIT * float(np.sqrt(material.G / rho))


def drive_limit(material, phi0: float, stress: bool = False) -> tuple[float, str, str]:
    """(largest wall speed [m/s] or stress [Pa], unit, reason) of the small-elastic-strain
    hypoelastic law (:data:`rheology.elastic.ELASTIC_STRAIN_LIMIT`): an impulsively moved wall
    launches a shear wave of elastic strain u/c_s into the jammed skeleton, a wall stress tau
    strains it by tau/G (annular_shear: 1.53 m/s, 18 times the fast Fig. 3 speed; 3.8e4 Pa)."""
    if stress:
        return ELASTIC_STRAIN_LIMIT * material.G, "Pa", (
            f"0.1 G, G = {material.G:g} Pa of {material.name}: a larger stress strains the "
            "hypoelastic law past 10 % elastic strain")
    top = max_wall_speed(material, phi0)
    return top, "m/s", (f"0.1 c_s, c_s = sqrt(G/rho) = {top / ELASTIC_STRAIN_LIMIT:.4g} m/s for "
                        f"{material.name} at phi = {phi0:g}: a faster wall strains the "
                        "hypoelastic law past 10 % elastic strain")


def _drive_bound(stress: bool, cap: Bound) -> Bound:
    """The upper bound of the drive at ``{"material": m, "phi0": phi0}``: :func:`drive_limit`,
    or the physical ``cap`` (runkit.limits) where that is lower."""
    def at(p):
        top, _, why = drive_limit(p["material"], p["phi0"], stress)
        return (top, why) if top <= cap.value else (cap.value, cap.why)
    return Bound(lambda p: at(p)[0], True, lambda p: at(p)[1])


#: The moving wall's speed [m/s] and shear stress [Pa]: the physical speeds and stresses
#: (runkit.limits), at most :func:`drive_limit` of the material at phi0 (params: material, phi0).
WALL_SPEED = Param(SPEED_MIN, _drive_bound(False, SPEED_MAX), unit="m/s")
WALL_STRESS = Param(STRESS_MIN, _drive_bound(True, STRESS_MAX), unit="Pa")
#: The floor of the granular pressure [Pa] (a stress) and the rate form's step [s] (a duration).
CONTACT_PRESSURE = Param(STRESS_MIN, STRESS_MAX, unit="Pa")
RATE_STEP = Param(TIME_MIN, TIME_MAX, unit="s")
#: The volume fraction: at least the dilute limit (runkit.limits), below phi_j of the material
#: (params: material).
PHI0 = Param(PHI_MIN, Bound(lambda p: p["material"].phi_j, False,
                            lambda p: f"steady flow needs phi below phi_j = {p['material'].phi_j} "
                                      f"of {p['material'].name}"))


def interleaved(n: int, per_cell: int, stress_driven: bool):
    """Interleaved unknowns (banded Jacobian): [v_0 if stress-driven], then per cell j its
    ``per_cell`` unknowns and v_{j+1} (not after the last cell: the fixed wall). Returns (index
    of each cell's first unknown (n,), index of each face's velocity (n + 1,; -1: prescribed),
    size)."""
    first = int(stress_driven) + (per_cell + 1) * np.arange(n, dtype=np.int64)
    i_v = np.full(n + 1, -1, dtype=np.int64)
    i_v[0] = 0 if stress_driven else -1
    i_v[1:n] = first[:-1] + per_cell
    return first, i_v, int(stress_driven) + n * (per_cell + 1) - 1


#: Stress components stored per cell, in this order.
STRESS_COMPONENTS = ("sigma_rr", "sigma_thth", "sigma_zz", "sigma_rth")


@dataclass(frozen=True)
class Couette:
    """A 1-D Couette problem ready to integrate (see the module docstring for the equations).

    Parameters
    ----------
    material : Material
        Needs G, K, K0, rho_s and rho_f (two-phase mode also d > 0).
    grid : Grid
    mode : {"locked", "two-phase"}
    wall_speed : float, optional
        Speed of the moving wall [m/s] (bob surface speed u_i). Exactly one of wall_speed and
        wall_stress is given.
    wall_stress : float, optional
        Mixture shear stress applied by the moving wall [Pa] (stress-controlled run). The
        drive is in :data:`WALL_SPEED` or :data:`WALL_STRESS`.
    ramp_time : float
        The drive rises linearly from 0 over this time [s]; 0 = impulsive start
        (:data:`RAMP_TIME`).
    phi0 : float, optional
        Uniform initial volume fraction (:data:`PHI0`: PHI_MIN <= phi0 < phi_j); default
        ``material.phi0``.
    contact_pressure : float
        Floor of the granular pressure [Pa] (and its initial value): see
        :func:`shear1d.kernels.local_updates`; results do not depend on it while it is far below
        tau* (checked in the tests).
    rate_step : float, optional
        delta [s] of the rate form used by the implicit (IDA) integration (see
        :func:`shear1d.kernels.ode_rhs`); default: chosen by :meth:`rate_step_at`.

    Every parameter is checked here, once (ValueError; :class:`runkit.params.OutOfRange`
    naming it, with its range and reason), the gap and bob radius against the grain size too.
    """

    material: Material
    grid: Grid
    mode: str = "locked"
    wall_speed: float | None = None
    wall_stress: float | None = None
    ramp_time: float = 0.0
    phi0: float | None = None
    contact_pressure: float = 1e-3
    rate_step: float | None = None
    _cache: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        m = self.material
        if not isinstance(m, Material):
            raise ValueError(f"material must be a rheology Material, got {type(m).__name__}")
        if not isinstance(self.grid, Grid):
            raise ValueError(f"grid must be a shear1d Grid, got {type(self.grid).__name__}")
        object.__setattr__(self, "mode", Param(kind="choice", choices=MODES).check("mode",
                                                                                  self.mode))
        m.require("G", "K", "K0", "rho_s", "rho_f")
        if self.mode == "two-phase" and not m.d > 0:     # a Material's d: 0 (unset) or physical
            raise OutOfRange("d", shown(m.d), interval_text(GRAIN_MIN.value, True, GRAIN_MAX.value,
                                                            True, "m"),
                             f"material {m.name}: the two-phase mode needs the grain diameter "
                             "for Darcy drag; set it, e.g. --set d=1e-5")
        if (self.wall_speed is None) == (self.wall_stress is None):
            raise ValueError("give exactly one of wall_speed [m/s] and wall_stress [Pa]")
        phi0 = m.phi0 if self.phi0 is None else self.phi0
        if phi0 is None:
            raise ValueError(f"phi0 is not set for material {m.name}: pass phi0=...")
        object.__setattr__(self, "phi0", PHI0.check("phi0", phi0, {"material": m}))
        name = "wall_stress" if self.wall_speed is None else "wall_speed"
        (WALL_STRESS if self.wall_speed is None else WALL_SPEED).check(
            name, self.drive_amplitude, {"material": m, "phi0": self.phi0})
        RAMP_TIME.check("ramp_time", self.ramp_time)
        CONTACT_PRESSURE.check("contact_pressure", self.contact_pressure)
        if self.rate_step is not None:
            RATE_STEP.check("rate_step", self.rate_step)
        self._check_grains()

    def _check_grains(self) -> None:
        """The gap holds cells of CELL_MIN_GRAINS grains, the bob R_INNER_MIN_GRAINS grains
        (:mod:`shear1d.geometry`); OutOfRange naming r_inner, r_outer or gap."""
        d, g = self.material.d, self.grid
        if not d > 0:
            return
        grains = f"d = {d:g} m of {self.material.name}"
        if g.annular and g.inner < R_INNER_MIN_GRAINS * d:
            raise OutOfRange("r_inner", f"{g.inner:g} m", f"[{R_INNER_MIN_GRAINS * d:.4g}, "
                             f"{LENGTH_MAX.value:g}] m", f"the bob must be a continuum wall, a "
                             f"radius of at least {R_INNER_MIN_GRAINS:g} grain diameters: {grains}")
        lo = min_gap(g.n, d)
        if g.gap < lo * (1.0 - 1e-12):
            most = int(g.gap / (CELL_MIN_GRAINS * d))
            at = f"a bob radius of {g.inner:g} m and " if g.annular else ""
            raise OutOfRange("r_outer" if g.annular else "gap", f"{g.outer:g} m",
                             f"[{g.inner + lo:.4g}, {LENGTH_MAX.value:g}] m",
                             f"at {at}{g.n} cells each cell of the gap must hold at least "
                             f"{CELL_MIN_GRAINS:g} grain, {grains}, the continuum the model "
                             f"describes" + (f"; or at most {most} cells at this gap"
                                             if most >= 4 else ""))

    # ------------------------------------------------------------------ layout of the unknowns
    @property
    def two_phase(self) -> bool:
        return self.mode == "two-phase"

    @property
    def stress_driven(self) -> bool:
        return self.wall_stress is not None

    @property
    def drive_amplitude(self) -> float:
        return float(self.wall_stress if self.stress_driven else self.wall_speed)

    @property
    def block(self) -> int:
        """Unknowns per cell: 4 stress components, f, (phi), and the velocity of its outer face."""
        return 7 if self.two_phase else 6

    def layout(self) -> dict[str, np.ndarray]:
        """Index arrays into the unknown vector (:func:`interleaved`; per cell sigma (4,
        STRESS_COMPONENTS), f, [phi]; i_v -1 for a face with a prescribed velocity)."""
        def make():
            first, i_v, size = interleaved(self.grid.n, self.block - 1, self.stress_driven)
            i_phi = first + 5 if self.two_phase else np.full(self.grid.n, -1, dtype=np.int64)
            return dict(i_S=first[:, None] + np.arange(4), i_f=first + 4, i_phi=i_phi, i_v=i_v,
                        size=np.int64(size))
        return self._cached("layout", make)

    @property
    def size(self) -> int:
        return int(self.layout()["size"])

    def bandwidth(self) -> int:
        """Half bandwidth of the Jacobian of :meth:`rhs` (both sides).

        A face couples to its two cells and their outer faces (one block each side); with Darcy
        flux a cell couples to both neighbouring cells (two blocks less the velocity entries).
        Checked against a dense finite-difference Jacobian in the tests.
        """
        return 2 * self.block - 2 if self.two_phase else self.block

    # ------------------------------------------------------------------ state
    def initial_state(self) -> np.ndarray:
        """At rest: isotropic contact pressure, f = 0, uniform phi0, v = 0 inside the gap."""
        n = self.grid.n
        S = np.zeros((n, 4))
        S[:, :3] = -self.contact_pressure
        return self.pack(np.zeros(n + 1), S, np.zeros(n), np.full(n, self.phi0))

    def pack(self, v, sigma, f, phi) -> np.ndarray:
        """State vector from fields: v (faces), sigma (n, 4), f, phi (cells)."""
        lay = self.layout()
        y = np.empty(self.size)
        y[lay["i_S"]] = sigma
        y[lay["i_f"]] = f
        if self.two_phase:
            y[lay["i_phi"]] = phi
        iv = lay["i_v"]
        y[iv[iv >= 0]] = np.asarray(v)[iv >= 0]
        return y

    def unpack(self, y: np.ndarray, t: float) -> dict[str, np.ndarray]:
        """Fields of one state vector: v (faces), sigma (n, 4) in STRESS_COMPONENTS order, f, phi."""
        lay = self.layout()
        y = np.asarray(y, dtype=float)
        n = self.grid.n
        v = np.empty(n + 1)
        kernels.face_velocities(y, lay["i_v"], self.wall_velocity(t), v)
        S, f, phi = np.empty((n, 4)), np.empty(n), np.empty(n)
        kernels.unpack_cells(y, lay["i_S"], lay["i_f"], lay["i_phi"], self._phi_fixed(), S, f, phi)
        return dict(v=v, sigma=S, f=f, phi=phi)

    def wall_velocity(self, t: float) -> float:
        """Prescribed speed of the moving wall at t [m/s] (0 if it is stress-driven)."""
        return 0.0 if self.stress_driven else float(kernels.drive(t, self.drive_amplitude,
                                                                  self.ramp_time))

    def wall_traction(self, t: float) -> float:
        """Applied wall shear stress at t [Pa] (0 if velocity-driven)."""
        return float(kernels.drive(t, self.drive_amplitude, self.ramp_time)) if self.stress_driven \
            else 0.0

    # ------------------------------------------------------------------ coefficients
    def metrics(self) -> dict:
        """Grid metrics for the kernels (see :mod:`shear1d.geometry`)."""
        def make():
            g = self.grid
            (cg, w), (A, M, A_wall) = g.shear_metric(), g.momentum_metric()
            a, V, hoop_c, hoop_f = g.flux_metric()
            return dict(cg=cg, w=w, A=A, M=M, A_wall=float(A_wall), a=a, V=V, hoop_c=hoop_c,
                        hoop_f=hoop_f, dx=float(g.dx))
        return self._cached("metrics", make)

    def parameters(self) -> np.ndarray:
        return self._cached("P", lambda: kernel_parameters(self.material))

    def coefficients(self, phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(rho at faces [kg/m^3], fluid viscosity per cell [Pa s], Darcy mobility n^2/C at faces
        [m^2/(Pa s)]) for volume fractions ``phi`` per cell (see kernels.phase_coefficients)."""
        m = self.material
        phi = np.ascontiguousarray(phi, dtype=float)
        n = phi.shape[0]
        rho, eta_f, mob = np.empty(n + 1), np.empty(n), np.empty(n + 1)
        kernels.phase_coefficients(phi, m.eta0, m.d, m.rho_s, m.rho_f, self.two_phase, rho, eta_f,
                                   mob)
        return rho, eta_f, mob

    # ------------------------------------------------------------------ right-hand side
    def rate_step_at(self, rtol: float, t: float) -> float:
        """delta [s] of the rate form at time t [s] for tolerance rtol: ``rate_step`` if set,
        else rtol times the longer of the flow time and the time elapsed.

        Plastic relaxations faster than delta are capped at ~1/delta: a start-up lets the fluid
        carry the load for ~delta instead of the Maxwell time, while steady states and the
        elastic response stay exact. Growing with t, delta keeps the start-up accurate and the
        quasi-steady stretches cheap (there the compaction switch is a kink of sharpness
        1/delta). Two-phase, delta is at most a tenth of a cell's consolidation time: beyond it
        one delta-step's volumetric strain outweighs a small contact pressure and the local
        update would separate a cell that dilatancy keeps in contact.
        """
        if self.rate_step is not None:
            return float(self.rate_step)
        delta = rtol * max(self.flow_time(), float(t))
        if self.two_phase:
            delta = min(delta, 0.1 * self.consolidation_time())
        return float(delta)

    def consolidation_time(self) -> float:
        """dx^2/D with D = (K + 4G/3) n^2/C the Darcy consolidation diffusivity at phi0 [s]."""
        if not self.two_phase:
            return float("inf")
        m = self.material
        mobility = self.coefficients(np.full(2, self.phi0))[2][1]
        return self.grid.dx ** 2 / ((m.K + 4.0 * m.G / 3.0) * mobility)

    def rhs(self, t: float, y: np.ndarray, ydot: np.ndarray, delta: float,
            diag: np.ndarray | None = None) -> None:
        """dy/dt at (t, y) into ``ydot``: the local update used as a rate over ``delta`` [s].

        ``diag`` (n, 4) receives shear rate, plastic shear rate, pressure and case per cell.
        Raises RuntimeError if the local update fails in a cell.
        """
        lay, mt = self.layout(), self.metrics()
        if diag is None:
            diag = self._scratch("diag", (self.grid.n, kernels.NDIAG))
        m = self.material
        bad = kernels.ode_rhs(
            y, self.wall_velocity(t), self.wall_traction(t), lay["i_S"], lay["i_f"],
            lay["i_phi"], lay["i_v"], self._phi_fixed(), mt["cg"], mt["w"], mt["A"], mt["M"],
            mt["A_wall"], mt["a"], mt["V"], mt["hoop_c"], mt["hoop_f"], mt["dx"], m.eta0, m.d,
            m.rho_s, m.rho_f, self.parameters(), float(delta), self.contact_pressure, ydot, diag,
            self._scratch("work", (self.grid.n, 11)))
        if bad >= 0:
            st = self.unpack(y, t)
            raise RuntimeError(
                f"Table 8 local update failed in cell {bad} (r = {self.grid.centres[bad]:.6g} m) "
                f"at t = {t:.6g} s: phi = {st['phi'][bad]:.6g}, f = {st['f'][bad]:.6g}, "
                f"sigma (rr, thth, zz, rth) = {st['sigma'][bad].tolist()} Pa")

    def diagnostics(self, t: float, y: np.ndarray, delta: float) -> np.ndarray:
        """Per-cell (shear rate, plastic shear rate, pressure, case) at a state, (n, 4).

        The pressure is the state's -tr(sigma)/3; the plastic shear rate and the case are those of
        the local update over ``delta`` [s] from that state.
        """
        diag = np.empty((self.grid.n, kernels.NDIAG))
        self.rhs(t, y, np.empty(self.size), delta, diag)
        diag[:, kernels.DIAG_FIELDS.index("pressure")] = -y[self.layout()["i_S"][:, :3]].mean(
            axis=1)
        return diag

    def _cached(self, key: str, make):
        if key not in self._cache:
            self._cache[key] = make()
        return self._cache[key]

    def _phi_fixed(self) -> np.ndarray:
        return self._cached("phi_fixed", lambda: np.full(self.grid.n, self.phi0))

    def _scratch(self, name: str, shape) -> np.ndarray:
        return self._cached("scratch_" + name, lambda: np.empty(shape))

    # ------------------------------------------------------------------ scales
    def velocity_scale(self) -> float:
        """Characteristic speed [m/s]: the wall speed, or stress-driven tau_w H/(eta0 eta_r)
        (positive: the drive is at least SPEED_MIN or STRESS_MIN)."""
        if not self.stress_driven:
            return abs(self.drive_amplitude)
        eta = self.material.eta0 * (1 + 2.5 * self.phi0 + float(granular_viscosity(
            self.phi0, 0.0, self.material)))
        return self.drive_amplitude * self.grid.gap / eta

    def flow_time(self) -> float:
        """Time for the moving wall to travel one gap at the velocity scale [s]."""
        return self.grid.gap / self.velocity_scale()

    def stress_scale(self) -> float:
        """Characteristic stress [Pa] for tolerances: tau* of the material."""
        return float(self.material.tau_star)
