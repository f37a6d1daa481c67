"""Fig. 3's fast case after the jammed band reaches the outer wall: "all flow ceases".

The paper's caption: at u_i = 84 mm/s a rigidly rotating block grows from the bob, and "when the
edge of this block reaches the outer edge of the annular shear cell, all flow ceases". The
shear1d cell (Table 4 ``annular_shear``, locked mixture, bob driven at u_i with no slip) is run
to 0.31 rad with one term of the law changed at a time, to find what the flow does once the band
is at the wall and what makes it move again:

- ``table8``: the law as published (Delta = 0, so f_m = f_jam at phi0 and the structure can only
  approach jamming: phi_m(f) > phi0 throughout);
- ``no buckling decay``: 1/eta_B = 0 (varphi_1 = varphi_2 = 0), the relaxation of f at rest;
- ``mpm_3d``: the author's yield rules (elastic admissibility below jamming);
- ``Delta = 0.35``: f_m = 0.35 > f_jam = 0.303, so the band jams (f > f_jam: a solid skeleton);
- ``4 G``: the skeleton's elastic moduli G and K four times Table 4's.

Measured for each: the rotation where the bulk speed (mean |v|/u_i beyond 20 % of the gap)
first falls below 0.1 after its largest value (the band, rotating with the bob, has reached the
wall: the flow "stops"), where it next exceeds 0.1 (it "restarts"), the structure at the bob,
the bob's shear stress and the distance of the profile from the steady Newtonian one A r + B/r
at 0.31 rad. The annulus driven by a no-slip bob cannot come to rest: an elastic solid and a
uniform-viscosity fluid both move as A r + B/r there, so a profile near the Newtonian one is no
evidence of unjamming. This module may import the tiers.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rheology import f_jam
from runkit.plotting import plt
from shear1d import analysis
from shear1d.analytic import annular_steady
from shear1d.integrate import solve
from shear1d.scenes import annular_shear_jamming

from .framework import Verdict, case, save_figure, write_csv

FAST = 0.084
#: bulk-speed level of a stopped flow (shear1d's flow_stopped event)
STOP = 0.1
VARIANTS = {
    "table8": {},
    "no buckling decay": dict(varphi1=0.0, varphi2=0.0),
    "mpm_3d": dict(rules="mpm_3d"),
    "Delta = 0.35": dict(Delta=0.35),
    "4 G": dict(G=4 * 3.8e5, K=4 * 8.3e5),
}


def _after_front(overrides: dict, n_cells: int) -> dict:
    """One run of the fast cell: its series (rotation, bulk speed, bob stress, f at the bob over
    f_jam) and the measured rotations and values (None where a rotation does not occur)."""
    pb, t_end = annular_shear_jamming(FAST, n_cells=n_cells, mode="locked", **overrides)
    res = solve(pb, t_end, n_out=310)
    g = pb.grid
    rot = res.t * FAST / g.inner
    v = res.field("v")
    bulk = np.array([analysis.bulk_speed(g, vk, FAST) for vk in v])
    fj = float(f_jam(pb.phi0, pb.material))
    f_bob = res.field("f")[:, 0] / fj
    tau = np.abs(res.field("shear_stress")[:, 0])
    peak = int(np.argmax(bulk))                   # the band rotating with the bob, at the wall
    late = np.flatnonzero((bulk < STOP) & (np.arange(rot.size) > peak))
    stop = int(late[0]) if late.size else None
    up = np.flatnonzero((bulk > STOP) & (np.arange(rot.size) > (stop or rot.size)))
    restart = int(up[0]) if up.size else None
    newt = annular_steady(g.faces, g.inner, g.outer, FAST)
    return dict(rot=rot, bulk=bulk, tau=tau, f_bob=f_bob,
                stop=None if stop is None else float(rot[stop]),
                restart=None if restart is None else float(rot[restart]),
                f_bob_after_stop_min=None if stop is None else float(f_bob[stop:].min()),
                f_gap_min_end=float(res.field("f")[-1].min() / fj),
                tau_stop=None if stop is None else float(tau[stop]), tau_end=float(tau[-1]),
                newtonian_deviation_end=float(np.abs(v[-1] - newt).max() / FAST))


def _rad(x) -> str:
    return "never" if x is None else f"{x:.3f}"


@case("shear1d", "shear1d_fig3_after_the_front",
      "Fig. 3, u_i = 84 mm/s after the band reaches the wall: what stops and restarts the flow")
def fig3_after_the_front(out: Path, quick: bool) -> Verdict:
    runs = {k: _after_front(kw, 60 if quick else 100) for k, kw in VARIANTS.items()}
    rows = [{"variant": k, "stop_rad": r["stop"], "restart_rad": r["restart"],
             "f_bob_over_f_jam_after_stop_min": r["f_bob_after_stop_min"],
             "f_over_f_jam_min_end": r["f_gap_min_end"], "bob_stress_at_stop_Pa": r["tau_stop"],
             "bob_stress_end_Pa": r["tau_end"],
             "newtonian_deviation_end_over_u": r["newtonian_deviation_end"]}
            for k, r in runs.items()]
    write_csv(out, "after_the_front.csv", rows, ["stop_rad", "restart_rad",
                                                 "f_bob_over_f_jam_after_stop_min",
                                                 "bob_stress_at_stop_Pa"])
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.3))
    for k, r in runs.items():
        ax[0].plot(r["rot"], r["bulk"], label=k)
        ax[1].semilogy(r["rot"], r["tau"], label=k)
        ax[2].semilogy(r["rot"], np.abs(1.0 - r["f_bob"]), label=k)
    ax[0].axhline(STOP, color="k", lw=0.7, ls=":")
    ax[0].set(xlabel="bob rotation [rad]", ylabel="bulk speed / u_i (beyond 20 % of the gap)")
    ax[1].set(xlabel="bob rotation [rad]", ylabel="bob shear stress [Pa]")
    ax[2].set(xlabel="bob rotation [rad]", ylabel="|1 - f/f_jam| at the bob")
    ax[0].legend(fontsize=8)
    fig.suptitle("shear1d, Fig. 3 fast case (locked, u_i = 84 mm/s): one term changed at a time")
    figs = [save_figure(fig, out, "after_the_front.png")]
    base, nob, m3, jam = (runs[k] for k in ("table8", "no buckling decay", "mpm_3d",
                                            "Delta = 0.35"))
    same = all(r["stop"] is not None and r["restart"] is not None
               and abs(r["stop"] - base["stop"]) <= 0.01
               and abs(r["restart"] - base["restart"]) <= 0.01 for r in (nob, m3))
    passed = (base["stop"] is not None and base["restart"] is not None and same
              and base["f_bob_after_stop_min"] >= 0.99 and base["tau_end"] > base["tau_stop"]
              and jam["restart"] is not None and jam["f_gap_min_end"] > 1.0
              and jam["newtonian_deviation_end"] <= 0.1)
    table = "; ".join(
        f"{k}: stop {_rad(r['stop'])}, restart {_rad(r['restart'])} rad, f_bob/f_jam >= "
        f"{r['f_bob_after_stop_min'] or float('nan'):.4f} after the stop, f/f_jam >= "
        f"{r['f_gap_min_end']:.3f} at the end, bob stress {r['tau_stop'] or float('nan'):.0f} -> "
        f"{r['tau_end']:.0f} Pa, |v - v_N|/u_i {r['newtonian_deviation_end']:.3f} at 0.31 rad"
        for k, r in runs.items())
    return Verdict(
        criterion="the paper's 'all flow ceases' as the model has it: with table8 the bulk speed "
                  "falls below 0.1 u_i after the band reaches the wall and exceeds it again; "
                  "with the buckling decay off and with the mpm_3d rules the stop and the "
                  "restart are the same (within 0.01 rad: neither the relaxation of f at rest "
                  "nor the zero-stress or elastic rules restart it); f at the bob stays >= 0.99 "
                  "f_jam after the stop (the band does not unjam) while the bob stress rises; a "
                  "band that jams (Delta = 0.35, f > f_jam across the gap) stops and restarts too "
                  "and ends within 0.1 u_i of the Newtonian profile (the driven annulus moves as "
                  "A r + B/r, solid or fluid)",
        measured=table + f"; {60 if quick else 100} cells, IDA",
        passed=bool(passed), figures=figs)
