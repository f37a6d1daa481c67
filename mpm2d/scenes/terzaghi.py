"""Terzaghi consolidation with the two-phase formulation (granular + fluid points, one grid).

Equations (Table 8 with a linear elastic skeleton, no gravity)::

    phi rho_s dv_s/dt = div sigma' - phi grad p_f - C (v_s - v_f)
    n rho_f dv_f/dt   = div tau_f  - n grad p_f   + C (v_s - v_f)
    p_f = kappa ln(rho_f/rho_0f),  (n/rho_f) D rho_f/Dt = -div(phi v_s + n v_f)
    C = 18 phi n eta0 F(phi, Re)/d^2  (Beetstra F, rheology.laws.beetstra_F)

A column of height H (periodic sideways, impermeable fixed base, drained free top) starts at
rest and unloaded; a surface load q(t) on its grains rises with a half-cosine ramp over
t_r = ramp T_r H^2/cv and then stays. Quasi-static small-strain theory (Terzaghi, with a
compressible fluid: Biot) gives the pore pressure as Terzaghi's series superposed over the
ramp (Duhamel, closed form: mpm2d.analytic.terzaghi_pressure), with
cv = (n^2/C)/(1/E_oed + n/kappa), E_oed = K + 4G/3, undrained pressure p0 = B q,
B = 1/(1 + n E_oed/kappa), and the settlement s = H (q(t) - mean p)/E_oed.

Why a ramp: switching the load (or the drainage) on instantly launches the fast, undrained Biot
wave, which the quasi-static theory omits and nothing damps; a ramp ten times the undrained
transit time H/c_u keeps those waves below ~1% of p0. The defaults give H^2/cv = 5 s, transit
H/c_u = 25 ms, drag time n rho_f/C = 0.6 ms: inertia is negligible.

Parameters: height H [m], cells (over H), width_cells, ppc, K, G [Pa] (skeleton), rho_s,
rho_f [kg/m^3], phi, eta0 [Pa s], d [m] (grain diameter, sets the drag), kappa [Pa],
load q [Pa], ramp (T_r = cv t_r/H^2), t_end_T (end time as T = cv t/H^2), cfl, transfer.

Run: ``mpm2d run terzaghi --out terzaghi`` (mode: two-phase)
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from rheology import laws
from runkit import limits
from runkit.io import atomic_write_csv
from runkit.limits import ge

from .. import analytic, plots
from ..bodies import box
from ..grid import Grid
from ..materials import LinearElastic, NewtonianFluid
from ..output import load_frames
from ..particles import ParticleSet
from . import spec
from ..run import Scene
from ..simulation import Drag, Simulation

#: times (as T = cv t/H^2) of the compared pressure profiles
PROFILE_T = (0.1, 0.2, 0.4, 0.8)


#: the shortest load ramp, in undrained transit times H/c_u (the waves it launches stay below
#: ~1% of the undrained pressure p0)
RAMP_TRANSITS = 10.0


def constants(params: dict) -> dict:
    """cv, B, p0, E_oed, the drag coefficient and the time scales of a parameter set."""
    phi, n = params["phi"], 1.0 - params["phi"]
    C = 18.0 * phi * n * params["eta0"] * float(laws.beetstra_F(phi, 0.0)) / params["d"] ** 2
    E_oed = params["K"] + 4.0 * params["G"] / 3.0
    cv, B = analytic.terzaghi_coefficients(E_oed, params["kappa"], n, C)
    t_c = params["height"] ** 2 / cv
    rho = phi * params["rho_s"] + n * params["rho_f"]
    c_u = np.sqrt((E_oed + params["kappa"] / n) / rho)
    return {"C_Pa_s_per_m2": C, "E_oed_Pa": E_oed, "cv_m2_per_s": cv, "B": B,
            "p0_Pa": B * params["load"], "t_c_s": t_c, "ramp_s": params["ramp"] * t_c,
            "transit_s": params["height"] / c_u, "drag_time_s": n * params["rho_f"] / C}


def _steps(p) -> tuple:
    """(first step [s], end time [s], fewest steps) from the parameters: the wave limit of the
    skeleton (K + 4G/3 on phi rho_s) or the pore fluid (kappa on n rho_f), or the fluid's
    viscous limit, whichever is smallest (at rest, unloaded); ``t_end_T`` times H^2/cv."""
    phases = [(LinearElastic(p["rho_s"], p["K"], p["G"]), p["phi"] * p["rho_s"]),
              (NewtonianFluid(p["eta0"], p["rho_f"], p["kappa"]), (1.0 - p["phi"]) * p["rho_f"])]
    return (spec.first_step(p["cfl"], p["height"] / p["cells"], phases),
            p["t_end_T"] * constants(p)["t_c_s"], 1)


@spec.parameters_of(
    height=spec.length("layer height H"),
    cells=spec.cells("cells over H"),
    width_cells=spec.cells("cells across (periodic)", 2, 1000, hi_why="a 1-D consolidation: "
                           "more cells across only repeat the column"),
    ppc=spec.ppc(),
    K=spec.modulus("skeleton bulk modulus"), G=spec.modulus("skeleton shear modulus"),
    rho_s=spec.density("grain density"), rho_f=spec.density("fluid density"),
    phi=spec.physical(limits.PHI_MIN, limits.lt(1.0, "grains fill at most the whole volume"),
                      "", "solid volume fraction"),
    eta0=spec.viscosity(),
    d=spec.grain_size(),
    kappa=spec.modulus("fluid bulk modulus"),
    load=spec.stress("load q on the drained top",
                     above=ge(lambda p: 1e-9 * (p["K"] + 4.0 * p["G"] / 3.0),
                              "settlement strain q/(K + 4G/3) >= 1e-9: a smaller one is lost "
                              "in the rounding of the positions")),
    ramp=spec.physical(
        limits.gt(0.0, "a load applied at once launches the undrained Biot wave"),
        limits.le(10.0, "a ramp of 10 consolidation times: the layer has consolidated long "
                  "before it ends"), "", "load ramp T_r = cv t_r/H^2",
        above=ge(lambda p: RAMP_TRANSITS * constants(p)["transit_s"] / constants(p)["t_c_s"],
                 f"{RAMP_TRANSITS:g} undrained transit times H/c_u: a faster ramp launches "
                 "the Biot waves the quasi-static theory omits (above ~1% of p0)")),
    t_end_T=spec.runs_for("end time as T = cv t/H^2", 100.0, "T = 100: consolidated to "
                          "e^-250"),
    cfl=spec.cfl(), transfer=spec.transfer(),
    size=lambda p: (2 * p["width_cells"] * p["cells"] * p["ppc"] ** 2,
                    (p["width_cells"] + 5) * (p["cells"] + 9)),
    steps=lambda p: _steps(p))
def setup(height=1.0, cells=32, width_cells=2, ppc=2, K=5.0e5, G=3.75e5, rho_s=2650.0,
          rho_f=1000.0, phi=0.5, eta0=1.0e-3, d=3.3e-4, kappa=1.0e6, load=1.0e3, ramp=0.1,
          t_end_T=0.8, cfl=0.5, transfer="apic"):
    params = dict(locals())                   # every parameter, as checked
    k = constants(params)
    h = height / cells
    grid = Grid(width_cells, cells + 4, h, boundaries=dict(xmin="periodic", xmax="periodic",
                                                          ymin="noslip", ymax="free"))
    x, area = box((0.0, 0.0), (width_cells * h, height), h / ppc)
    top = x[:, 1] > height - h / ppc
    fext = np.zeros_like(x)
    fext[top, 1] = -1e-300                          # marks the loaded points (load set per step)
    grains = ParticleSet("grains", LinearElastic(rho_s, K, G), x, area, phi=phi, fext=fext,
                         fext_offset=(0.0, 0.5 * h / ppc))
    fluid = ParticleSet("fluid", NewtonianFluid(eta0, rho_f, kappa), x, area, phi=phi)
    sim = Simulation(grid, [grains, fluid], mode="two-phase", drag=Drag(eta0, d, rho_f),
                     cfl=cfl, transfer=transfer, name="terzaghi")
    top_ids = np.flatnonzero(top)                   # ids are the creation order
    y_top0 = float(np.mean(x[top, 1]))
    width = h / ppc

    def load_now(sim):
        g = sim.sets[0]
        loaded = g.fext[:, 1] != 0.0
        g.fext[loaded, 1] = -load * width * analytic.ramp(sim.t, k["ramp_s"]) - 1e-300

    def record(sim):
        g, f = sim.sets[0], sim.sets[1]
        return {"load_Pa": load * float(analytic.ramp(sim.t, k["ramp_s"])),
                "settlement_m": y_top0 - float(np.mean(g.x[np.isin(g.id, top_ids), 1])),
                "mean_pore_pressure_Pa": float(np.sum(f.pf * f.V) / np.sum(f.V)),
                "bottom_pore_pressure_Pa": float(np.mean(f.pf[f.x[:, 1] < h / ppc]))}

    return Scene(sim, t_end_T * k["t_c_s"], params, frames=10, history_rows=400, record=record,
                 report=lambda sim, hist, out: report(hist, out, params),
                 before_step=load_now, frame_times=tuple(T * k["t_c_s"] for T in PROFILE_T),
                 notes="mode two-phase: granular and fluid points")


def profiles(out) -> list[tuple]:
    """(t, y, p_f) of the fluid points at the profile times, from the run's event frames."""
    return [(float(f["time_s"]), f["fluid.x"][:, 1], f["fluid.pore_pressure_Pa"])
            for f in load_frames(out, "event")]


def exact_pressure(depth, t, params):
    k = constants(params)
    return analytic.terzaghi_pressure(depth, t, params["height"], k["p0_Pa"], k["cv_m2_per_s"],
                                      k["ramp_s"])


def analyse(history, params, profiles) -> dict:
    """Pore pressure at the fluid points at the stored times against the exact solution, and
    the settlement history.

    Profile error = max over points below the top cell (depth > h) of |p - p_exact|/p0.
    Settlement error = max |s - s_exact| / max s_exact over the history.
    """
    k = constants(params)
    H, h = params["height"], params["height"] / params["cells"]
    rows = []
    for t, y, pf in profiles:
        depth = H - y
        keep = (depth > h) & (depth < H)
        ex = exact_pressure(depth[keep], t, params)
        rows.append({"time_s": t, "T": t / k["t_c_s"],
                     "max_error": float(np.max(np.abs(pf[keep] - ex)) / k["p0_Pa"]),
                     "rms_error": float(np.sqrt(np.mean((pf[keep] - ex) ** 2)) / k["p0_Pa"])})
    s_ex = settlement_exact(history["time_s"], params)
    s_err = float(np.max(np.abs(history["settlement_m"] - s_ex)) / np.max(np.abs(s_ex)))
    return {"constants": k, "profiles": rows, "settlement_error": s_err}


def settlement_exact(t, params):
    """s = H (q(t) - mean p(t))/E_oed [m]."""
    k = constants(params)
    q = params["load"] * analytic.ramp(t, k["ramp_s"])
    pm = analytic.terzaghi_mean_pressure(t, params["height"], k["p0_Pa"], k["cv_m2_per_s"],
                                         k["ramp_s"])
    return params["height"] * (q - pm) / k["E_oed_Pa"]


def report(history, out, params):
    prof = profiles(out)
    res = analyse(history, params, prof)
    k = res["constants"]
    table = pd.DataFrame(res["profiles"])
    table["settlement_error"] = res["settlement_error"]
    atomic_write_csv(out / "terzaghi_result.csv", table)
    fig, (a1, a2) = plots.plt.subplots(1, 2, figsize=(12, 5))
    H = params["height"]
    z = np.linspace(0, H, 200)
    for i, (t, y, pf) in enumerate(prof):
        col = plots.plt.cm.viridis(i / max(len(prof) - 1, 1))
        a1.plot(exact_pressure(z, t, params) / k["p0_Pa"], z, "-", color=col,
                label=f"T = {t / k['t_c_s']:.3g}")
        a1.plot(pf / k["p0_Pa"], H - y, ".", color=col, ms=3)
    a1.set_xlabel("p_f / p0  (p0 = B q)")
    a1.set_ylabel("depth below the drained top [m]")
    a1.invert_yaxis()
    if prof:
        a1.legend(title="lines exact, dots MPM")
    a1.set_title(f"Terzaghi consolidation, two-phase MPM ({params['cells']} cells)")
    t = history["time_s"]
    a2.plot(t / k["t_c_s"], settlement_exact(t, params) * 1e3, "k-", lw=2,
            label="exact H (q - mean p)/E_oed")
    a2.plot(t / k["t_c_s"], history["settlement_m"] * 1e3, "r--", label="MPM (top grains)")
    a2.axvline(params["ramp"], color="0.6", ls=":", label="end of load ramp")
    a2.set_xlabel("T = cv t / H^2")
    a2.set_ylabel("settlement [mm]")
    a2.set_title(f"settlement error {100 * res['settlement_error']:.2f}%")
    a2.legend()
    return [plots.save(fig, out / "terzaghi.png")]
