"""Grid update: nodal velocities from momentum and force, and the two-phase coupling at nodes.

One phase (single phase or locked mixture)::

    v_i^old = p_i / m_i,   v_i* = (p_i + dt f_i) / m_i            (explicit, symplectic Euler)

Two phases (Table 8 momentum balances, granular s and fluid f on the same nodes):

- nodal volume fraction phi_i = (sum_s N V_s phi_s) / V_i, with V_i the nodal mixture volume
  (the larger of the fluid and granular points' sum_p N_ip V_p, both of which tile the mixture);
- pore pressure: the fluid points carry -p_f 1 in divergence form, giving the nodal force
  F^p_i ~ -int N_i grad p_f dV; it is shared as -(1 - n) grad p_f on the granular phase and
  -n grad p_f on the fluid (buoyancy, Table 8), i.e. phi_i F^p_i and (1 - phi_i) F^p_i;
- drag, implicit and in closed form (the drag time rho/C is ~1e-5 s for d = 5.85 um, far
  below any explicit step): with the nodal coefficient C_i = V_i^s C(phi_i^s) [kg/s], where
  V_i^s = sum_s N V_p and phi_i^s = sum_s N V_p phi_p / V_i^s are the granular points' own
  volume and concentration (so a grain at the edge of a granular region, on a partly covered
  node, feels the bulk drag), C = 18 phi (1 - phi) eta0 F(phi, Re)/d^2 (rheology's
  drag_coefficient with the Beetstra F of rheology.laws), backward Euler for the pair
  gives f_d = C_i / (1 + dt C_i (1/m_s + 1/m_f)) (v_s* - v_f*), v_s -= dt f_d/m_s,
  v_f += dt f_d/m_f: exact momentum exchange, unconditionally stable, and the phases lock
  together as C -> inf;
- mixture volume flux q_i = phi_i v_s + (1 - phi_i) v_f, whose divergence drives the fluid true
  density (Table 8).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from rheology import laws
from rheology.numba_cache import guard

from .kernels import dual
from .grid import FPX, FPY, FX, FY, MX, MY, M, V, VS

guard(__file__)                          # drop cached kernels if rheology's laws changed


#: largest nodal volume fraction used for the drag and the pressure split
PHI_NODE_MAX = 0.95


@dual
def velocities(G, dt, vg, vg_old):
    """v_old = p/m and v* = (p + dt f)/m at nodes with mass (0 elsewhere)."""
    for I in nb.prange(G.shape[0]):
        for J in range(G.shape[1]):
            m = G[I, J, M]
            if m > 0.0:
                vg_old[I, J, 0] = G[I, J, MX] / m
                vg_old[I, J, 1] = G[I, J, MY] / m
                vg[I, J, 0] = (G[I, J, MX] + dt * G[I, J, FX]) / m
                vg[I, J, 1] = (G[I, J, MY] + dt * G[I, J, FY]) / m
            else:
                vg_old[I, J, 0] = vg_old[I, J, 1] = 0.0
                vg[I, J, 0] = vg[I, J, 1] = 0.0


@dual
def mixture_flux(Gs, Gf, phi, vs, vf, q):
    """q_i = phi v_s + (1 - phi) v_f (v_s or v_f alone where only one phase has mass)."""
    for I in nb.prange(Gs.shape[0]):
        for J in range(Gs.shape[1]):
            ms, mf = Gs[I, J, M], Gf[I, J, M]
            for c in range(2):
                if ms > 0.0 and mf > 0.0:
                    q[I, J, c] = phi[I, J] * vs[I, J, c] + (1.0 - phi[I, J]) * vf[I, J, c]
                elif ms > 0.0:
                    q[I, J, c] = vs[I, J, c]
                else:
                    q[I, J, c] = vf[I, J, c]


@dual
def two_phase_nodes(Gs, Gf, phi, dt, vs, vs_old, vf, vf_old, eta0, d, rho_f, drag_out):
    """The two-phase node pass in one sweep (one parallel region): per node the volume fraction
    phi_i (clipped to PHI_NODE_MAX), the pore-pressure force shared as phi_i F^p on the grains and
    (1 - phi_i) F^p on the fluid (buoyancy), both phases' :func:`velocities`, and the closed-form
    backward-Euler drag where both phases have mass (the module docstring gives the equations;
    C from rheology.laws.drag_coefficient with Re = rho_f |v_s* - v_f*| d / eta0 of the predicted
    velocities). ``drag_out`` receives |f_d| [N] per node for diagnostics."""
    for I in nb.prange(Gs.shape[0]):
        for J in range(Gs.shape[1]):
            vmix = max(Gs[I, J, V], Gf[I, J, V])
            ph_i = min(Gs[I, J, VS] / vmix, PHI_NODE_MAX) if vmix > 0.0 else 0.0
            phi[I, J] = ph_i
            fpx, fpy = Gf[I, J, FPX], Gf[I, J, FPY]
            Gs[I, J, FX] += ph_i * fpx
            Gs[I, J, FY] += ph_i * fpy
            Gf[I, J, FX] += (1.0 - ph_i) * fpx
            Gf[I, J, FY] += (1.0 - ph_i) * fpy
            ms, mf = Gs[I, J, M], Gf[I, J, M]
            if ms > 0.0:
                vs_old[I, J, 0] = Gs[I, J, MX] / ms
                vs_old[I, J, 1] = Gs[I, J, MY] / ms
                vs[I, J, 0] = (Gs[I, J, MX] + dt * Gs[I, J, FX]) / ms
                vs[I, J, 1] = (Gs[I, J, MY] + dt * Gs[I, J, FY]) / ms
            else:
                vs_old[I, J, 0] = vs_old[I, J, 1] = 0.0
                vs[I, J, 0] = vs[I, J, 1] = 0.0
            if mf > 0.0:
                vf_old[I, J, 0] = Gf[I, J, MX] / mf
                vf_old[I, J, 1] = Gf[I, J, MY] / mf
                vf[I, J, 0] = (Gf[I, J, MX] + dt * Gf[I, J, FX]) / mf
                vf[I, J, 1] = (Gf[I, J, MY] + dt * Gf[I, J, FY]) / mf
            else:
                vf_old[I, J, 0] = vf_old[I, J, 1] = 0.0
                vf[I, J, 0] = vf[I, J, 1] = 0.0
            drag_out[I, J] = 0.0
            if ms <= 0.0 or mf <= 0.0:
                continue
            vgr = Gs[I, J, V]
            ph = min(Gs[I, J, VS] / vgr, PHI_NODE_MAX)
            dvx = vs[I, J, 0] - vf[I, J, 0]
            dvy = vs[I, J, 1] - vf[I, J, 1]
            Re = rho_f * np.sqrt(dvx * dvx + dvy * dvy) * d / eta0
            c = laws.drag_coefficient(ph, Re, eta0, d) * vgr
            k = c / (1.0 + dt * c * (1.0 / ms + 1.0 / mf))
            fx, fy = k * dvx, k * dvy
            vs[I, J, 0] -= dt * fx / ms
            vs[I, J, 1] -= dt * fy / ms
            vf[I, J, 0] += dt * fx / mf
            vf[I, J, 1] += dt * fy / mf
            drag_out[I, J] = np.sqrt(fx * fx + fy * fy)
