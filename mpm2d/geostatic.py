"""Beds at rest: one function that puts a bed (any mode) into its geostatic state.

:func:`geostatic` sets the stress, pore pressure, fluid density, masses and structure of the
bed's points so that the bed is in equilibrium with gravity and consistent with its law, then
(optionally, default) removes the discretisation's residual by a short damped relaxation of the
bed alone (dynamic relaxation, as in the "gravity loading" step of geotechnical codes).

The state (depth d below the free surface y_s, gravity g along -y):

- the structure at rest: with no shear the Table 8 law drives f to 0 (dF/dt = -K0 taubar/eta_B f at
  gdot_p = 0); a bed denser than phi_j is jammed whatever f (Baumgarten's code sets f = 1 there), so
  f_rest = 0 for phi < phi_j and 1 otherwise;
- a LOOSE suspension (phi < phi_m(f_rest)) cannot carry a granular stress at rest: the law's
  compaction rule (Table 8, P3) relaxes any granular pressure within ~1e-4 s, so the granular
  stress is 0 and the pore fluid carries the whole weight, p_f = rho_mix g d (locked mixture; in
  two-phase mode the grains settle at the Stokes rate and their buoyant weight reaches the fluid
  through the drag: the same p_f);
- a JAMMED suspension (phi >= phi_m(f_rest)) or an elastic skeleton carries the buoyant weight
  sigma'_v = -(rho_mix - rho_f) g d, sigma'_h = K_lat sigma'_v, with p_f = rho_f g d;
- a single-phase elastic bed: sigma_v = -rho g d, sigma_h = K_lat sigma_v;
- default K_lat = nu/(1 - nu) = (3K - 2G)/(3K + 4G), the oedometric (laterally confined elastic)
  ratio of the skeleton's moduli.

Relaxation: the bed's sets alone (no bodies) are stepped with a velocity damping until the
largest speed is below ``v_tol`` (or ``max_steps``); their stresses, volumes, pore pressures and
states are kept, their positions, velocities and affine matrices reset, f reset to f_rest.
On a bed whose points tile it on the grid's layout (n x n per cell from a node line, so that the
surface lies on a multiple of h/n) the analytic field is already an exact discrete equilibrium:
the engine's well-balanced body force (:func:`mpm2d.shape.hydrostatic_coefficient`) removes the
particle quadrature's free-surface residual (which once put the top cell row 19.5 % below
rho g d in every mode) and its axis correction the mirror-wall one; the relaxation then changes
the field by < 0.05 % (tests). It stays for what those do not cover: beds whose points are not
on that layout, the radial corner residual at an axisymmetric floor (~1e-4 of a node's weight).
"""

from __future__ import annotations

import math

import numpy as np

from rheology import laws
from runkit.params import check_range

from .materials import LinearElastic, NewtonianFluid, Suspension
from .simulation import Simulation


def _k_oed(K, G):
    return (3.0 * K - 2.0 * G) / (3.0 * K + 4.0 * G)


def _set_stress(s, sv, K_lat):
    st = np.zeros((len(s), 3, 3))
    st[:, 1, 1] = sv
    st[:, 0, 0] = st[:, 2, 2] = K_lat * sv
    s.stress[:] = st
    s.sp[:] = np.stack([st[:, 0, 0], st[:, 0, 1], st[:, 1, 1], st[:, 2, 2]], axis=1)


def rest_structure(phi, m) -> np.ndarray:
    """f at rest: 0 below phi_j, 1 at or above it (see module docstring)."""
    return np.where(np.asarray(phi) >= m.phi_j, 1.0, 0.0)


def geostatic(sim, surface=None, K_lat=None, sets=None, relax=True, v_tol=None,
              max_steps=4000, log=None) -> dict:
    """Put the bed of ``sim`` at rest under its gravity (any mode); returns a summary dict.

    Parameters
    ----------
    sim : Simulation (gravity along -y, before its first step)
    surface : float, optional
        Height y_s of the free surface [m]; default: the highest point face of the bed.
    K_lat : float, optional
        Lateral stress ratio sigma_h/sigma_v of the granular (or elastic) stress [-]; default
        the oedometric nu/(1 - nu) of the set's moduli.
    sets : names of the bed's sets (default: every set not in ``sim.contact_sets``).
    relax : remove the discrete residual by damped relaxation (module docstring).
    v_tol : speed [m/s] at which the relaxation stops (default 1e-5 sqrt(g D)).

    Raises ValueError for a horizontal gravity component, a loose granular phase without fluid
    (it cannot rest), or K_lat outside [0, 2].
    """
    g = np.asarray(sim.gravity, float)
    if g[0] != 0.0 or g[1] >= 0.0:
        raise ValueError(f"geostatic: gravity = ({g[0]:g}, {g[1]:g}) m/s^2; valid: (0, -g) with "
                         "g > 0 (a bed rests under gravity along -y)")
    gy = -g[1]
    if sim.step_count:
        raise ValueError("geostatic: call it before the first step")
    names = list(sets) if sets is not None else [s.name for s in sim.sets
                                                  if s.name not in sim.contact_sets]
    bed = [s for s in sim.sets if s.name in names]
    if len(bed) != len(names):
        raise ValueError(f"geostatic: sets {names} not all in the simulation")
    axi = sim.grid.axisymmetric

    def side(s):
        a = s.V / s.x[:, 0] if axi else s.V
        return np.sqrt(a)

    if surface is None:
        surface = max(float(np.max(s.x[:, 1] + 0.5 * side(s))) for s in bed)
    if K_lat is not None:
        check_range("K_lat", K_lat, 0.0, 2.0, note="a lateral stress from none to twice the "
                                                    "vertical one")
    fluid_sets = [s for s in bed if isinstance(s.material, NewtonianFluid)]
    summary = {"surface_m": surface, "mode": sim.mode}
    for s in bed:
        d = np.maximum(surface - s.x[:, 1], 0.0)
        mat = s.material
        if isinstance(mat, LinearElastic):
            kl = _k_oed(mat.K, mat.G) if K_lat is None else K_lat
            if sim.mode == "single phase":
                rho = mat.rho * s.svol / s.V
                _set_stress(s, -rho * gy * d, kl)
            else:                           # an elastic skeleton under a fluid: buoyant weight
                phi = s.svol / s.V
                rf = fluid_sets[0].material.rho if fluid_sets else 0.0
                _set_stress(s, -phi * (mat.rho - rf) * gy * d, kl)
            summary[f"{s.name}.K_lat"] = kl
        elif isinstance(mat, Suspension):
            m = mat.m
            phi = s.svol / s.V
            f0 = rest_structure(phi, m)
            jammed = phi >= laws.phi_m(f0, m.phi_c, m.phi_j)
            kl = _k_oed(m.K, m.G) if K_lat is None else K_lat
            if mat.locked:
                rho_f = m.rho_f
                for _ in range(3):          # the fluid's density depends on its pressure
                    rho_mix = phi * m.rho_s + (1.0 - phi) * rho_f
                    pf = np.where(jammed, rho_f * gy * d, rho_mix * gy * d)
                    rho_f = m.rho_f * np.exp(pf / m.kappa)
                s.arrays["m"] = (phi * m.rho_s + (1.0 - phi) * rho_f) * s.V
                sv = np.where(jammed, -(rho_mix - rho_f) * gy * d, 0.0)
                _set_stress(s, sv, kl)
                s.pf[:] = pf
                s.sp[:, [0, 2, 3]] -= pf[:, None]
            elif sim.mode == "two-phase":
                rf = fluid_sets[0].material.rho if fluid_sets else m.rho_f
                sv = np.where(jammed, -phi * (m.rho_s - rf) * gy * d, 0.0)
                _set_stress(s, sv, kl)
            else:
                if not np.all(jammed):
                    raise ValueError(f"geostatic: set {s.name}: a loose granular phase "
                                     f"(phi < phi_m) without its fluid cannot rest; use a "
                                     "locked mixture or two phases")
                _set_stress(s, -phi * m.rho_s * gy * d, kl)
            s.f[:] = f0
            s.arrays["f_rest"] = f0
            summary[f"{s.name}.K_lat"] = kl
            summary[f"{s.name}.jammed_fraction"] = float(np.mean(jammed))
        elif isinstance(mat, NewtonianFluid):
            pass
        else:
            raise ValueError(f"geostatic: set {s.name}: unsupported material {mat.name}")
    for s in fluid_sets:                    # two-phase pore fluid
        mat = s.material
        d = np.maximum(surface - s.x[:, 1], 0.0)
        phi = 1.0 - s.n
        grains = [b for b in bed if isinstance(b.material, Suspension)]
        loose = True
        rho_s = 0.0
        if grains:
            gm = grains[0].material.m
            rho_s = gm.rho_s
            f0 = rest_structure(phi, gm)
            loose = phi < laws.phi_m(f0, gm.phi_c, gm.phi_j)
        else:
            el = [b for b in bed if isinstance(b.material, LinearElastic)]
            rho_s = el[0].material.rho if el else 0.0
            loose = np.zeros(len(s), dtype=bool)
        rho_f = np.full(len(s), mat.rho)
        for _ in range(3):
            pf = np.where(loose, (phi * rho_s + (1.0 - phi) * rho_f) * gy * d, rho_f * gy * d)
            rho_f = mat.rho * np.exp(pf / mat.kappa)
        s.rho_f[:] = rho_f
        s.arrays["m"] = s.n * rho_f * s.V
        s.pf[:] = pf
        s.stress[:] = -pf[:, None, None] * np.eye(3)
        s.sp[:] = 0.0                        # two-phase: the pore pressure acts through pf
    if relax:
        summary.update(_relax(sim, bed, surface, gy, v_tol, max_steps, log))
    for s in bed:
        if "f_rest" in s.arrays:
            s.f[:] = s.arrays.pop("f_rest")
    return summary


def _relax(sim, bed, surface, gy, v_tol, max_steps, log):
    """Damped relaxation of the bed alone; keeps the material state, resets the kinematics."""
    depth = surface - min(float(np.min(s.x[:, 1])) for s in bed)
    if v_tol is None:
        v_tol = 1e-5 * math.sqrt(gy * max(depth, sim.grid.h))
    kw = dict(mode=sim.mode, gravity=tuple(sim.gravity), transfer=sim.transfer, cfl=sim.cfl,
              cfl_visc=sim.cfl_visc, chunks=sim.nc, name=f"{sim.name}-geostatic")
    if sim.two_phase:
        kw["drag"] = sim.drag
    tmp = Simulation(sim.grid, bed, [], **kw)
    keep = {s.name: (s.x.copy(), s.id.copy()) for s in bed}
    c2 = max(s.material.wave_modulus() * float(np.max(s.V / s.m)) for s in bed)
    period = 4.0 * depth / math.sqrt(c2)
    vmax = np.inf
    n = 0
    t_min = 3.0 * period                    # let the slowest mode ring and decay at least once
    for n in range(1, max_steps + 1):
        dt = tmp.step()
        damp = min(0.5, 8.0 * math.pi * dt / period)
        vmax = 0.0
        for s in bed:
            # in place through the arrays (``s.v *= ...`` would bind an instance attribute that
            # shadows s.arrays["v"] and survives a checkpoint load)
            np.multiply(s.arrays["v"], 1.0 - damp, out=s.arrays["v"])
            np.multiply(s.arrays["C"], 1.0 - damp, out=s.arrays["C"])
            vmax = max(vmax, float(np.abs(s.v).max()))
        if vmax < v_tol and tmp.t > t_min:
            break
    for s in bed:
        x0, id0 = keep[s.name]
        if not np.array_equal(s.id, id0):   # tmp re-sorted the points: the original order
            pos = np.empty(len(s), dtype=np.int64)
            pos[np.searchsorted(np.sort(s.id), s.id)] = np.arange(len(s))
            s.permute(pos[np.searchsorted(np.sort(s.id), id0)])
        s.x[:] = x0
        s.v[:] = 0.0
        s.C[:] = 0.0
        s.L[:] = 0.0
    sim._sort()
    if log:
        log(f"geostatic relaxation: {n} steps, max |v| {vmax:.3g} m/s (tol {v_tol:.3g})")
    return {"relax_steps": n, "relax_vmax_m_per_s": vmax}
