"""The analysis of a solved Couette run: bob rotation, flow stop and restart, the jammed band and
its front, the summary numbers and the tables the files and figures are made of."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

import rheology

from rheology.run_end import run_record

from . import analysis
from .analytic import annular_steady
from .integrate import EVENTS, FLOW_STOP_LEVEL, Result

ROTATIONS = (0.0, 0.1, 0.2, 0.31)


@dataclass
class SceneRun:
    """One solved scene: its tag (file prefix), result and summary numbers."""

    tag: str
    result: Result
    summary: dict


def run_tag(u_inner: float, mode: str) -> str:
    return f"u{u_inner * 1e3:g}mm_s_{mode}"


def rotation_of(result: Result, t) -> np.ndarray:
    """Bob rotation [rad] at times t [s] (integral of u(t)/R_i, ramp included)."""
    pb = result.problem
    t = np.asarray(t, dtype=float)
    u, ramp = pb.drive_amplitude, pb.ramp_time
    dist = np.where(t < ramp, 0.5 * u * t ** 2 / ramp if ramp > 0 else 0.0, u * (t - 0.5 * ramp))
    return dist / pb.grid.inner


def flow_stop_time(result: Result) -> float | None:
    """Time [s] the flow stopped after the band reached the outer wall (None if it did not)."""
    wall = next(iter(result.events.get("front_at_wall", [])), None)
    return next((x for x in result.events.get("flow_stopped", []) if wall is None or x >= wall),
                None)


def flow_restart_time(result: Result) -> float | None:
    """The first output time [s] after the flow stopped (:func:`flow_stop_time`) at which the
    bulk speed is back above FLOW_STOP_LEVEL of the wall speed (None: it stays stopped)."""
    stop = flow_stop_time(result)
    if stop is None:
        return None
    g, u, v = result.problem.grid, result.problem.drive_amplitude, result.field("v")
    return next((float(t) for t, vk in zip(result.t, v)
                 if t > stop and analysis.bulk_speed(g, vk, u) >= FLOW_STOP_LEVEL), None)


def band_present(result: Result) -> np.ndarray:
    """(n_out,) bool: outputs at which a jammed band grows from the moving wall: f >=
    f_jam(phi0)/2 in the cell at the wall, until the band reaches the outer wall
    (``front_at_wall``) or the flow stops (``flow_stopped``). After that the rigid-ratio crossing
    is the edge of the decelerating layer at the bob, no front of a band."""
    pb = result.problem
    fjam = float(rheology.f_jam(pb.phi0, pb.material))
    f = result.field("f")
    band = f[:, 0] >= 0.5 * fjam
    ends = [ts[0] for ts in (result.events.get("front_at_wall", []),
                             result.events.get("flow_stopped", [])) if ts]
    if ends:
        band &= result.t <= min(ends)
    return band


def band_front(result: Result) -> np.ndarray:
    """Kinematic front position [m] where a jammed band exists (:func:`band_present`), NaN
    elsewhere (undefined by construction: no band, no front)."""
    return np.where(band_present(result), result.front(), np.nan)


#: Summary keys null where undefined by construction: the front fit when no band crossed 10 % of
#: the gap or fewer than 3 outputs fell in the crossing; the band's rigidity and front without one.
NULLABLE = ("front_speed_m_per_s", "front_speed_over_u_inner", "front_fit_r2",
            "front_fit_gap_reached", "front_fit_intercept_m", "front_fit_rotation_rad",
            "structure_front_speed_m_per_s", "structure_front_fit_r2", "band_rigidity_mean",
            "band_rigidity_min", "max_front_position_m")


def summarize(result: Result) -> dict:
    """Front speed and linearity, rigidity, events, conservation, Newtonian deviation and how
    the run ended (:func:`rheology.run_end.run_record`). Values undefined by construction are NaN
    (null: :data:`NULLABLE`); no wall time (a resumed run's files are an uninterrupted run's)."""
    pb, g = result.problem, result.problem.grid
    m, u = pb.material, pb.drive_amplitude
    v, f, phi = result.field("v"), result.field("f"), result.field("phi")
    fr = front_frame(result)
    front = fr["front_m"].to_numpy()
    band = np.isfinite(front)           # the front where a jammed band exists (band_present)
    sfront = np.where(band, fr["structure_front_m"].to_numpy(), np.nan)
    fit = analysis.front_fit(result.t, front, g)
    sfit = analysis.front_fit(result.t, sfront, g)
    rot = rotation_of(result, result.t)
    window = (result.t >= fit["t_start"]) & (result.t <= fit["t_end"]) & band
    rigid = fr["band_rigidity"].to_numpy()[window]
    rigid = rigid[np.isfinite(rigid)]
    solids = phi @ g.cell_volumes()
    ev = {k: [float(x) for x in result.events.get(k, [])] for k in EVENTS}
    wall_t = ev["front_at_wall"][0] if ev["front_at_wall"] else None
    stop_t, again_t = flow_stop_time(result), flow_restart_time(result)

    def rot_at(t):
        return None if t is None else float(rotation_of(result, t))

    newt = {}
    for target in ROTATIONS[1:]:
        k = int(np.argmin(np.abs(rot - target)))
        if abs(rot[k] - target) < 1e-3 + 0.5 * np.max(np.diff(rot), initial=0.0):
            vn = annular_steady(g.faces, g.inner, g.outer, u)
            newt[f"{target:g}"] = float(np.max(np.abs(v[k] - vn)) / u)
    nan = float("nan")
    stats = {k: (float(x) if isinstance(x, (float, np.floating)) else int(x))
             for k, x in result.stats.items()}
    return dict(
        u_inner_m_per_s=u, mode=pb.mode, method=result.method, n_cells=g.n, r_inner_m=g.inner,
        r_outer_m=g.outer, phi0=pb.phi0, t_end_s=float(result.t[-1]),
        rotation_end_rad=float(rot[-1]), solver=stats,
        front_speed_m_per_s=fit["speed"], front_speed_over_u_inner=fit["speed"] / u,
        front_fit_r2=fit["r2"], front_fit_intercept_m=fit["intercept"],
        front_fit_rotation_rad=[rot_at(fit["t_start"]), rot_at(fit["t_end"])],
        front_fit_gap_reached=fit["gap_reached"],
        front_crossed_gap=bool(fit["gap_reached"] >= analysis.WALL_FRACTION),
        structure_front_speed_m_per_s=sfit["speed"], structure_front_fit_r2=sfit["r2"],
        band_rigidity_mean=float(np.mean(rigid)) if rigid.size else nan,
        band_rigidity_min=float(np.min(rigid)) if rigid.size else nan,
        max_front_position_m=float(np.nanmax(front)) if band.any() else nan,
        front_at_wall_rotation_rad=rot_at(wall_t), flow_stopped_rotation_rad=rot_at(stop_t),
        flow_restarted_rotation_rad=rot_at(again_t),
        events_s=ev,
        newtonian_deviation_max_over_u=newt,
        f_max=float(f.max()), f_jam=float(rheology.f_jam(pb.phi0, m)), phi_min=float(phi.min()),
        phi_max=float(phi.max()),
        solid_volume_drift=float(np.max(np.abs(solids - solids[0])) / solids[0]),
        bob_shear_stress_max_Pa=float(fr["bob_shear_stress_Pa"].max()),
        granular_pressure_max_Pa=float(result.field("pressure").max()),
        **run_record([result.end] if result.end else []),
    )


# ----------------------------------------------------------------------------- files
def profile_frames(result: Result, rotations=ROTATIONS) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Velocity profiles (faces) and cell profiles at the outputs nearest the given rotations."""
    pb, g = result.problem, result.problem.grid
    rot = rotation_of(result, result.t)
    u = pb.drive_amplitude
    fields = {k: result.field(k) for k in ("v", "f", "phi", "sigma_rth", "pressure",
                                           "shear_stress", "shear_rate", "plastic_shear_rate")}
    vrows, crows = [], []
    for target in rotations:
        k = int(np.argmin(np.abs(rot - target)))
        vk = fields["v"][k]
        vrows.append(pd.DataFrame({
            "rotation_rad": rot[k], "time_s": result.t[k], "r_m": g.faces, "v_m_per_s": vk,
            "v_over_u_inner": vk / u, "v_over_omega_r": analysis.rigid_ratio(g, vk, u)}))
        crows.append(pd.DataFrame({
            "rotation_rad": rot[k], "time_s": result.t[k], "r_m": g.centres, "f": fields["f"][k],
            "phi": fields["phi"][k], "granular_shear_stress_Pa": np.abs(fields["sigma_rth"][k]),
            "granular_pressure_Pa": fields["pressure"][k],
            "shear_stress_Pa": np.abs(fields["shear_stress"][k]),
            "shear_rate_per_s": np.abs(fields["shear_rate"][k]),
            "plastic_shear_rate_per_s": fields["plastic_shear_rate"][k]}))
    return pd.concat(vrows, ignore_index=True), pd.concat(crows, ignore_index=True)


#: Columns of <tag>_front.csv left empty where undefined by construction: the front and the
#: band's rigidity where no jammed band exists (:func:`band_present`).
FRONT_EMPTY_OK = ("front_m", "band_rigidity")


def front_frame(result: Result) -> pd.DataFrame:
    """Front position and bob stress against time (front_m and band_rigidity empty where no
    jammed band exists)."""
    pb, g = result.problem, result.problem.grid
    u = pb.drive_amplitude
    v, f = result.field("v"), result.field("f")
    front = band_front(result)
    fjam = float(rheology.f_jam(pb.phi0, pb.material))
    tau = np.abs(result.field("shear_stress"))[:, 0] * (g.centres[0] / g.inner) ** 2
    rigidity = [analysis.band_rigidity(g, vv, u, fr) if np.isfinite(fr) else np.nan
                for vv, fr in zip(v, front)]
    return pd.DataFrame({
        "time_s": result.t, "rotation_rad": rotation_of(result, result.t), "front_m": front,
        "structure_front_m": [analysis.structure_front(g, ff, fjam) for ff in f],
        "band_rigidity": rigidity,
        "bulk_speed_over_u_inner": [analysis.bulk_speed(g, vv, u) for vv in v],
        "bob_shear_stress_Pa": tau,
        "bob_torque_per_height_N": 2 * np.pi * g.inner ** 2 * tau})


def fields_frame(result: Result, every: int = 1) -> pd.DataFrame:
    """Space-time fields at cell centres (long format): f, phi, v/(omega r), rates, pressure."""
    pb, g = result.problem, result.problem.grid
    u = pb.drive_amplitude
    idx = np.arange(0, len(result.t), max(1, every))
    v = result.field("v")[idx]
    vc = 0.5 * (v[:, 1:] + v[:, :-1])
    nt, n = len(idx), g.n
    return pd.DataFrame({
        "time_s": np.repeat(result.t[idx], n),
        "rotation_rad": np.repeat(rotation_of(result, result.t[idx]), n),
        "r_m": np.tile(g.centres, nt),
        "v_over_omega_r": (vc / g.rigid_speed(u, g.centres)).ravel(),
        "f": result.field("f")[idx].ravel(), "phi": result.field("phi")[idx].ravel(),
        "plastic_shear_rate_per_s": result.field("plastic_shear_rate")[idx].ravel(),
        "granular_pressure_Pa": result.field("pressure")[idx].ravel()})


def couette_profile_outputs(res: Result) -> np.ndarray:
    """Indices of the (up to 6) outputs whose velocity profiles are written and drawn."""
    return np.unique(np.linspace(0, len(res.t) - 1, 6).astype(int))


def couette_frames(res: Result) -> tuple[pd.DataFrame, pd.DataFrame]:
    """(profiles, wall history) of a plane Couette run: v(y) at a few times; wall speed, wall
    shear stress, mean shear rate and mean f against time."""
    g = res.problem.grid
    v, tau = res.field("v"), np.abs(res.field("shear_stress"))
    idx = couette_profile_outputs(res)
    prof = pd.concat([pd.DataFrame({"time_s": res.t[k], "y_m": g.faces, "v_m_per_s": v[k]})
                      for k in idx], ignore_index=True)
    wall = pd.DataFrame({"time_s": res.t, "wall_speed_m_per_s": v[:, 0],
                         "wall_shear_stress_Pa": tau[:, 0],
                         "mean_shear_rate_per_s": (v[:, 0] - v[:, -1]) / g.gap,
                         "f_mean": res.field("f").mean(axis=1)})
    return prof, wall


def jammed(summary: dict) -> bool:
    """Whether a run grew a jammed band (f reached half of f_jam(phi0) somewhere)."""
    return summary["f_max"] >= 0.5 * summary["f_jam"]
