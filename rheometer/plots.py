"""Figures of the rheometer's results (matplotlib, Agg backend), written atomically."""

from __future__ import annotations

import numpy as np
import pandas as pd

import rheology
from rheology.elastic import ELASTIC_STRAIN_LIMIT
from rheology.run_end import mark_end
from runkit.io import atomic_savefig
from runkit.plotting import plt

#: a log axis of a transient ends this far below its largest value: a relaxed stress or rate
#: lower than that is below the integrator's tolerance (rtol 1e-7 by default), its noise
LOG_FLOOR = 1e-9


def save(fig, path) -> str:
    """Write ``fig`` to ``path`` atomically and close it; returns the path as text."""
    try:
        atomic_savefig(fig, path)
    finally:
        plt.close(fig)
    return str(path)


def _finish(fig, axs, title: str, legend: int | None = 7, xlabel: str | None = None) -> None:
    """The common end of a figure: a grid (a legend of ``legend`` points, the x label) on every
    panel, the title, a tight layout."""
    for ax in np.atleast_1d(axs).ravel():
        ax.grid(True, which="both", alpha=0.25)
        if legend:
            ax.legend(fontsize=legend)
        if xlabel:
            ax.set_xlabel(xlabel)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()


def _colors(n: int):
    return plt.cm.viridis(np.linspace(0.0, 0.85, max(n, 1)))


def _each(df: pd.DataFrame, col: str = "phi"):
    """``(colour, value, rows)`` per distinct value of ``col``, in increasing order."""
    values = np.unique(df[col])
    return [(c, v, df[df[col] == v]) for c, v in zip(_colors(len(values)), values)]


def _positive(x):
    x = np.asarray(x, dtype=float)
    return np.where(x > 0, x, np.nan)


def _segments(stable):
    """Index ranges [i, j) of runs of equal ``stable`` values."""
    stable = np.asarray(stable, dtype=bool)
    cuts = np.flatnonzero(stable[1:] != stable[:-1]) + 1
    edges = np.concatenate([[0], cuts, [stable.size]])
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def _branch_lines(ax1, ax2, d: pd.DataFrame, m, ph, c, label):
    """The states of one phi under rate or mixture-stress control, drawn along the (unique)
    stress-parametrised curve: consecutive states of equal stability as one line, stable solid,
    unstable dashed; a lone state as a marker. The whole steady curve underneath, thin grey."""
    d = d.sort_values("granular_shear_stress_Pa")
    lo = max(float(d["granular_shear_stress_Pa"].min()) / 3.0, 1e-12)
    hi = float(d["granular_shear_stress_Pa"].max()) * 3.0
    full = rheology.steady_state_stress(np.geomspace(lo, hi, 400), ph, m)
    ax1.loglog(_positive(full.shear_rate), full.shear_stress, "-", color="0.6", lw=0.8,
               zorder=1)
    seen = set()
    for a, b in _segments(d["stable"].to_numpy()):
        s = d.iloc[a:b]
        stable = bool(s["stable"].iloc[0])
        key = (ph, stable)
        lab = None if key in seen else label + (" stable" if stable else " unstable")
        seen.add(key)
        style = dict(color=c, lw=2 if stable else 1.5, ls="-" if stable else "--", label=lab)
        if len(s) == 1:
            style.update(ls="none", marker="o" if stable else "x", ms=5,
                         mfc=c if stable else "none")
        ax1.loglog(s["shear_rate_per_s"], s["shear_stress_Pa"], **style)
        ax2.loglog(s["shear_stress_Pa"], _positive(s["viscosity_Pa_s"]),
                   **{k: v for k, v in style.items() if k != "label"})


def flow_curve_figure(df: pd.DataFrame, material, title: str | None = None):
    """Two panels: shear stress vs shear rate and viscosity vs shear stress (log-log), one curve
    per phi. Under rate or mixture-stress control every steady state is drawn along the branch
    it belongs to, stable branches solid and unstable ones dashed (legend), over the whole
    stress-parametrised steady curve (thin grey); gdot_DST of Eq. (33) dotted where DST exists."""
    m = rheology.get_material(material)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.4))
    for c, ph, d in _each(df):
        label = f"phi = {ph:g}"
        if "stable" in d.columns:
            _branch_lines(ax1, ax2, d, m, ph, c, label)
        else:
            d = d.sort_values("granular_shear_stress_Pa")
            ax1.loglog(_positive(d["shear_rate_per_s"]), d["shear_stress_Pa"], "-", color=c,
                       lw=2, label=label)
            ax2.loglog(d["shear_stress_Pa"], _positive(d["viscosity_Pa_s"]), "-", color=c, lw=2)
        if m.phi_c <= ph <= min(m.phi_star, m.phi_j) and m.varphi1 + m.varphi2 > 0:
            g = float(rheology.gdot_dst(ph, m))
            ax1.axvline(g, color=c, ls=":", lw=1)
    ax1.set(xlabel="shear rate [1/s]", ylabel="mixture shear stress [Pa]")
    ax1.set_title("flow curve (dotted: Eq. 33 DST rate; grey: whole steady curve)"
                  if "stable" in df.columns else "flow curve (dotted: Eq. 33 DST rate)",
                  fontsize=10)
    ax1.legend(fontsize=8)
    ax2.set(xlabel="mixture shear stress [Pa]", ylabel="viscosity [Pa s]")
    ax2.set_title("viscosity", fontsize=10)
    ctrl = df.attrs.get("control", "stress")
    _finish(fig, (ax1, ax2), title or f"{m.name}: steady flow curves ({ctrl} control)", None)
    return fig


def _f_axis(ax, values) -> None:
    """A structure axis that cannot make a tiny change look like a collapse: from 0 to at least
    1.15 max f (f is a fraction in [0, 1]); the relative change is given in the label."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    top = float(v.max()) if v.size else 1.0
    ax.set_ylim(0.0, max(1.15 * top, 0.05))
    note = f" (changes by {100 * (top - float(v.min())) / top:.3g}%)" if v.size and top > 0 else ""
    ax.set_ylabel("structure f [-]" + note, fontsize=9)


def _time_panels(axs, runs, panels, log_time: bool = False) -> None:
    """Columns against time, one colour per run (``runs``: (label, DataFrame)); ``panels``: per
    panel the (column, line style, width, what) drawn there, labelled ``label what``."""
    for c, (label, df) in zip(_colors(len(runs)), runs):
        t = df["time_s"].to_numpy()
        if log_time:
            t = np.where(t > 0, t, np.nan)
        for ax, lines in zip(axs, panels):
            for col, ls, lw, what in lines:
                ax.plot(t, df[col], ls, color=c, lw=lw,
                        label=" ".join(w for w in (label, what) if w))


def transient_figure(frames: dict, title: str, log_time: bool = False):
    """Mixture (solid) and granular (dashed) shear stress, shear rate and plastic rate, and the
    structure f against time; one colour per entry of ``frames`` (label -> DataFrame). The f axis
    starts at 0 (a 0.1% change stays a 0.1% change) and states the relative change."""
    fig, axs = plt.subplots(1, 3, figsize=(13, 3.9))
    _time_panels(axs, list(frames.items()), (
        (("shear_stress_Pa", "-", 2, "mixture"), ("granular_shear_stress_Pa", "--", 1, "granular")),
        (("shear_rate_per_s", "-", 2, "shear rate"),
         ("plastic_shear_rate_per_s", "--", 1, "plastic rate")),
        (("f", "-", 2, ""),)), log_time)
    for ax, col in ((axs[0], "shear_stress_Pa"), (axs[1], "shear_rate_per_s")):
        v = np.concatenate([d[col].to_numpy()[d["time_s"].to_numpy() > 0] for d in frames.values()])
        if v.size and np.all(v > 0) and v.max() > 100 * v.min():
            ax.set_yscale("log")
            ax.set_ylim(bottom=max(float(v.min()), LOG_FLOOR * float(v.max())))
    axs[0].set_ylabel("shear stress [Pa]")
    axs[1].set_ylabel("shear rate [1/s]")
    f_all = [d["f"].to_numpy()[d["time_s"].to_numpy() > 0 if log_time else slice(None)]
             for d in frames.values()]
    _f_axis(axs[2], np.concatenate(f_all) if f_all else [])
    for ax in axs if log_time else ():
        ax.set_xscale("log")
    _finish(fig, axs, title, xlabel="time [s]")
    return fig


def _step_marks(ax, df):
    """Dotted vertical lines at the step boundaries, numbered at the top."""
    starts = df.groupby("step")["time_s"].min()
    for k, tb in starts.items():
        if tb > float(df["time_s"].min()):
            ax.axvline(tb, color="0.5", lw=0.8, ls=":")
        ax.annotate(f"{k}", (tb, 1.0), xycoords=("data", "axes fraction"), fontsize=7,
                    color="0.35", ha="left", va="top", xytext=(2, -2),
                    textcoords="offset points")


def program_figure(df: pd.DataFrame, title: str):
    """Four panels: stress against rate (coloured by step, legend = program lines), then
    against time the mixture shear stress [Pa], the shear rate [1/s] (each on its own axis, log
    when it spans more than two decades, symlog when it also reaches zero: a rest step's zero
    rate and relaxed stress stay visible) and the structure f; step boundaries dotted and
    numbered."""
    fig, axs = plt.subplots(1, 4, figsize=(17, 4.2))
    labels = df.attrs.get("steps", [])
    ax = axs[0]
    oscillating = []
    for c, k, d in _each(df, "step"):
        lab = f"{k}: " + (labels[k - 1] if k - 1 < len(labels) else f"step {k}")
        if lab.split(": ", 1)[-1].startswith("oscillate"):
            oscillating.append(str(k))           # a loop through zero: the time panels show it
            continue
        g = _positive(d["shear_rate_per_s"])
        if np.any(np.isfinite(g)):
            ax.loglog(g, _positive(d["shear_stress_Pa"]), "-", color=c, lw=2, label=lab)
    if oscillating:
        ax.text(0.02, 0.02, f"oscillation step(s) {', '.join(oscillating)}: stress and rate "
                "change sign, see the time panels", transform=ax.transAxes, fontsize=7)
    ax.set(xlabel="shear rate [1/s]", ylabel="mixture shear stress [Pa]")
    ax.set_title("stress vs rate (steps in legend order)", fontsize=9)
    ax.legend(fontsize=6)
    t = df["time_s"]
    for ax, col, unit, colour in ((axs[1], "shear_stress_Pa", "mixture shear stress [Pa]", "C0"),
                                  (axs[2], "shear_rate_per_s", "shear rate [1/s]", "C1")):
        v = df[col].to_numpy()
        ax.plot(t, v, "-", lw=1.8, color=colour)
        pos = v[np.isfinite(v) & (v > 0)]
        if pos.size and pos.max() > 100 * pos.min():
            if np.any(np.isfinite(v) & (v <= 0)):      # a zero (rest, relaxed): symlog shows it
                thresh = max(float(pos.min()), 1e-6 * float(pos.max()))
                ax.set_yscale("symlog", linthresh=thresh)
                unit += f" (linear below {thresh:.2g})"
            else:
                ax.set_yscale("log")
                ax.set_ylim(bottom=max(float(pos.min()), LOG_FLOOR * float(pos.max())))
        ax.set_ylabel(unit)
    axs[3].plot(t, df["f"], "-", lw=2, color="C2")
    _f_axis(axs[3], df["f"])
    for ax in axs[1:]:
        ax.set_xlabel("time [s]")
        _step_marks(ax, df)
    _finish(fig, axs, title, None)
    return fig


def material_point_figure(df: pd.DataFrame, title: str):
    """Granular shear stress and pressure, normal-stress differences, f and phi against time,
    one colour per run (column ``phi0`` when several initial fractions were run; the column
    ``phi`` evolves under pressure control and is plotted, never used to select rows)."""
    fig, axs = plt.subplots(1, 3, figsize=(13, 3.9))
    runs = ([(f"phi0 = {p:g}", d) for p, d in df.groupby("phi0", sort=False)]
            if "phi0" in df.columns else [("", df)])
    ax_phi = axs[2].twinx()
    _time_panels([*axs, ax_phi], runs, (
        (("shear_stress_Pa", "-", 2, "sigma_xy"),
         ("granular_pressure_Pa", "--", 1.5, "pressure p")),
        (("N1_Pa", "-", 1.5, "N1 = s_xx - s_yy"), ("N2_Pa", "--", 1.5, "N2 = s_yy - s_zz")),
        (("f", "-", 2, "f"),), (("phi", ":", 1.5, "phi (right axis)"),)))
    axs[0].set_ylabel("granular stress [Pa]")
    axs[1].set_ylabel("normal-stress differences [Pa]")
    _f_axis(axs[2], df["f"])
    ax_phi.set_ylabel("volume fraction phi [-] (dotted)")
    h1, l1 = axs[2].get_legend_handles_labels()
    h2, l2 = ax_phi.get_legend_handles_labels()
    axs[2].legend(h1 + h2, l1 + l2, fontsize=7)
    for ax in axs[:2]:
        ax.legend(fontsize=7)
    _finish(fig, axs, title, None, "time [s]")
    return fig


# ------------------------------------------------------------------ oscillation
def _below_legend(fig, axs, ncol: int = 3):
    """One legend for the figure, below its panels (never over data); the labels of every
    panel, each once."""
    handles, labels = [], []
    for ax in np.atleast_1d(axs):
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels and not lab.startswith("_"):
                handles.append(h)
                labels.append(lab)
    fig.tight_layout(rect=(0, 0.03 + 0.035 * ((len(labels) + ncol - 1) // ncol), 1, 0.95))
    if labels:
        fig.legend(handles, labels, loc="lower center", ncol=ncol, fontsize=7, frameon=False)


#: a sweep's variable: (axis label, legend entry of one value)
_SWEEP = {"strain_amplitude": ("strain amplitude gamma0 [-]", "gamma0 = {:g}"),
          "stress_amplitude_Pa": ("stress amplitude sigma0 [Pa]", "sigma0 = {:g} Pa"),
          "frequency_Hz": ("frequency [Hz]", "{:g} Hz")}


def oscillation_figure(points: pd.DataFrame, title: str, dst_stress: float | None = None):
    """Sweep results: G' and G'' (symbols) with the linearised model's (lines), |eta*|, and the
    third-harmonic ratio I3/I1, against the strain amplitude (amplitude sweep) or the frequency
    (frequency sweep); one colour per phi (and per frequency in an amplitude sweep). Points whose
    elastic strain taubar/G passes :data:`rheology.elastic.ELASTIC_STRAIN_LIMIT` (the law outside
    its small-strain range) are drawn hollow over a shaded band; points whose solve failed
    (empty results, ``reason`` set) as crosses on the axis. Where ``dst_stress`` [Pa] is given,
    the amplitude where the peak stress first exceeds it is marked. One legend, below."""
    fig, axs = plt.subplots(1, 3, figsize=(15, 4.8))
    amp_sweep = points.groupby(["phi", "frequency_Hz"]).size().max() > 1
    amp = "stress_amplitude_Pa" if points["control"].iloc[0] == "stress" else "strain_amplitude"
    keys, xcol = (["phi", "frequency_Hz"], amp) if amp_sweep else (["phi", amp], "frequency_Hz")
    if "reason" not in points:
        points = points.assign(reason="")
    failed_all = points["reason"].fillna("") != ""
    # a failed point has no measured strain (stress control) or stress: group it by its drive
    groups = list(points.groupby(keys, sort=False, dropna=False))
    n_past = int((points["max_elastic_strain"] > ELASTIC_STRAIN_LIMIT).sum())
    for c, (key, d) in zip(_colors(len(groups)), groups):
        d = d.sort_values(xcol)
        lab = f"phi = {key[0]:g}, " + _SWEEP[keys[1]][1].format(key[1])
        fail = (d["reason"].fillna("") != "").to_numpy()
        ran = d[~fail]
        past = (ran["max_elastic_strain"] > ELASTIC_STRAIN_LIMIT).to_numpy()
        x = ran[xcol]
        panels = ((axs[0], "storage_modulus_Pa", "o", "-", ": G'"),
                  (axs[0], "loss_modulus_Pa", "s", "--", ": G''"),
                  (axs[1], "complex_viscosity_Pa_s", "o", "-", ""),
                  (axs[2], "I3_over_I1", "o", "-", ""))
        for k, (ax, col, mk, ls, what) in enumerate(panels):
            y = _positive(ran[col])
            ax.loglog(x, y, ls, color=c, lw=1.5, label=lab + what if k < 2 else "_",
                      marker=mk, ms=5, mfc="none" if mk == "s" else c,
                      markevery=list(np.flatnonzero(~past)))
            if past.any():
                ax.loglog(x[past], y[past], mk, color=c, ms=7, mfc="white", mew=1.6, ls="none")
        axs[0].loglog(x, _positive(ran["linear_storage_modulus_Pa"]), ":", color=c, lw=1,
                      label="linear G', G'' (small-amplitude model)")
        axs[0].loglog(x, _positive(ran["linear_loss_modulus_Pa"]), ":", color=c, lw=1)
        bad = ran[~ran["converged"].astype(bool)]
        if len(bad):
            axs[2].loglog(bad[xcol], _positive(bad["I3_over_I1"]), "kx", ms=8,
                          label="not periodic within the cycle limit")
        if past.any():
            lo, hi = float(x[past].min()), float(x[past].max())
            for ax in axs:
                ax.axvspan(lo / 1.25, hi * 1.25, color="crimson", alpha=0.08, lw=0,
                           label=f"hollow: elastic strain taubar/G > {ELASTIC_STRAIN_LIMIT:g} "
                                 "(law outside its small-strain range)")
        for xf in d.loc[fail, xcol].dropna():
            for ax in axs:
                ax.axvline(float(xf), color="k", ls=":", lw=1)
                ax.plot([float(xf)], [0.03], "kX", ms=9, transform=ax.get_xaxis_transform(),
                        label="solve failed (no result; reason in the CSV)")
        if amp_sweep and dst_stress is not None:
            over = ran[ran["peak_stress_Pa"] >= dst_stress]
            if len(over):
                g_c = float(over[xcol].iloc[0])
                for ax in axs:
                    ax.axvline(g_c, color=c, ls="-.", lw=1,
                               label=f"first amplitude with peak stress >= DST stress "
                                     f"{dst_stress:.3g} Pa")
    axs[0].set_ylabel("G' (o), G'' (s) [Pa]; dotted: linear G*(omega)")
    axs[1].set_ylabel("|eta*| = |G*|/omega [Pa s]")
    axs[2].set_ylabel("I3/I1 [-]")
    for ax in axs:
        ax.set_xlabel(_SWEEP[xcol][0])
        ax.grid(True, which="both", alpha=0.25)
    notes = []
    if n_past:
        notes.append(f"{n_past} of {len(points)} points past the elastic-strain limit")
    if failed_all.any():
        notes.append(f"{int(failed_all.sum())} failed")
    fig.suptitle(title + (f"\n{'; '.join(notes)}" if notes else ""), fontsize=11)
    _below_legend(fig, axs)
    return fig


def _normalised_cycle(w: pd.DataFrame):
    """One closed cycle of a waveform, normalised by its maxima: (strain, rate, stress,
    elastic stress, viscous stress, stress maximum)."""
    close = np.r_[np.arange(len(w)), 0]
    s = w["shear_stress_Pa"].to_numpy()[close]
    smax = np.max(np.abs(s)) or 1.0
    g = w["strain"].to_numpy()[close]
    gd = w["shear_rate_per_s"].to_numpy()[close]
    el = w["elastic_stress_Pa"].to_numpy()[close]
    vi = w["viscous_stress_Pa"].to_numpy()[close]
    return (g / (np.max(np.abs(g)) or 1.0), gd / (np.max(np.abs(gd)) or 1.0), s / smax,
            el / smax, vi / smax, smax)


#: normalised Lissajous curves closer than this everywhere are drawn as one (one legend entry
#: naming them all), so that no entry names a curve hidden under another
COINCIDE = 0.01


def lissajous_figure(waves: pd.DataFrame, title: str, max_curves: int = 8,
                     points: pd.DataFrame | None = None, dst_stress: float | None = None):
    """Lissajous-Bowditch curves of the periodic cycle: the elastic projection (stress against
    strain) and the viscous projection (stress against shear rate), each normalised by its
    maximum; Ewoldt's elastic and viscous stresses dashed (strain control). Consecutive points
    whose normalised curves coincide (within :data:`COINCIDE`) are drawn once and named
    together; of more than ``max_curves`` distinct curves, ``max_curves`` spread over the sweep
    are drawn. With the sweep's ``points`` (and ``dst_stress`` [Pa]) the first point whose peak
    stress reaches the DST stress (where thickening starts) is always drawn, and curves past
    the elastic-strain limit are dash-dotted and say so. One legend, below the panels."""
    fig, axs = plt.subplots(1, 2, figsize=(11, 5.6))
    groups = []                              # [point indices, normalised cycle]
    for k in np.unique(waves["point"]):
        cyc = _normalised_cycle(waves[waves["point"] == k])
        if groups and len(groups[-1][1][0]) == len(cyc[0]) and all(
                np.max(np.abs(a - b)) < COINCIDE for a, b in zip(groups[-1][1][:3], cyc[:3])):
            groups[-1][0].append(k)
            continue
        groups.append(([k], cyc))
    onset = None
    if points is not None and dst_stress is not None:
        over = [k for g in groups for k in g[0]
                if float(points.loc[k, "peak_stress_Pa"]) >= dst_stress]
        onset = over[0] if over else None
    if len(groups) > max_curves:
        keep = set(np.unique(np.round(np.linspace(0, len(groups) - 1, max_curves)).astype(int)))
        j = next((i for i, g in enumerate(groups) if onset in g[0]), None)
        if j is not None and j not in keep:
            keep.discard(min(keep - {0, len(groups) - 1}, key=lambda i: abs(i - j)))
            keep.add(j)
        groups = [groups[i] for i in sorted(keep)]
    for c, (ks, (g, gd, s, el, vi, smax)) in zip(_colors(len(groups)), groups):
        w = waves[waves["point"] == ks[0]]
        amps = [float(waves.loc[waves["point"] == k, "strain_amplitude"].iloc[0]) for k in ks]
        lab = (f"phi = {w['phi'].iloc[0]:g}, {w['frequency_Hz'].iloc[0]:g} Hz, gamma0 = "
               + (f"{amps[0]:.3g} (sigma_max = {smax:.3g} Pa)" if len(ks) == 1 else
                  f"{amps[0]:.3g} ... {amps[-1]:.3g} ({len(ks)} curves, coinciding)"))
        ls = "-"
        if points is not None:
            if onset in ks:
                lab += ": thickening starts (peak stress >= DST stress)"
            if (points.loc[ks, "max_elastic_strain"] > ELASTIC_STRAIN_LIMIT).any():
                lab += f": past the elastic-strain limit {ELASTIC_STRAIN_LIMIT:g}"
                ls = "-."
        axs[0].plot(g, s, ls, color=c, lw=1.8, label=lab)
        axs[1].plot(gd, s, ls, color=c, lw=1.8, label=lab)
        if np.all(np.isfinite(el)):
            axs[0].plot(g, el, "--", color=c, lw=0.9)
            axs[1].plot(gd, vi, "--", color=c, lw=0.9)
    axs[0].set_xlabel("strain / strain amplitude [-]")
    axs[0].set_title("elastic projection (dashed: elastic stress sigma')", fontsize=10)
    axs[1].set_xlabel("shear rate / max shear rate [-]")
    axs[1].set_title("viscous projection (dashed: viscous stress sigma'')", fontsize=10)
    for ax in axs:
        ax.set(ylabel="shear stress / max shear stress [-]", xlim=(-1.1, 1.1), ylim=(-1.1, 1.1))
        ax.axhline(0, color="0.7", lw=0.6)
        ax.axvline(0, color="0.7", lw=0.6)
        ax.grid(True, alpha=0.25)
    fig.suptitle(title, fontsize=11)
    _below_legend(fig, axs[:1], ncol=1)
    return fig


def parallel_plate_figure(df: pd.DataFrame, true_curve: pd.DataFrame | None, title: str):
    """The parallel plate: the true flow curve (the model's local steady curve, whole S-shape
    when ``true_curve`` is given), the apparent curve the instrument displays (sigma_a = 2 M/(pi
    R^3) against the rim rate) and the Weissenberg-Rabinowitsch-corrected points; right panel:
    the relative difference apparent/true - 1 and corrected/true - 1."""
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    for c, ph, d in _each(df):
        if true_curve is not None:
            t = true_curve[true_curve["phi"] == ph].sort_values("granular_shear_stress_Pa")
            ax1.loglog(_positive(t["shear_rate_per_s"]), t["shear_stress_Pa"], "-", color="0.6",
                       lw=1, label=f"phi = {ph:g}: whole steady curve")
        x, step = d["rim_shear_rate_per_s"], max(1, len(d) // 40)
        ax1.loglog(x, d["shear_stress_Pa"], "-", color=c, lw=2.5,
                   label=f"phi = {ph:g}: true (rim)")
        ax1.loglog(x, d["apparent_shear_stress_Pa"], "--", color=c, lw=1.5,
                   label=f"phi = {ph:g}: apparent 2M/(pi R^3)")
        ax1.loglog(x.iloc[::step], _positive(d["corrected_shear_stress_Pa"].iloc[::step]), "o",
                   color=c, ms=3.5, mfc="none", label=f"phi = {ph:g}: Weissenberg-Rabinowitsch")
        for col, ls, lw, what in (("apparent_shear_stress_Pa", "--", 1.5, "apparent"),
                                  ("corrected_shear_stress_Pa", "-", 1, "corrected")):
            ax2.semilogx(x, d[col] / d["shear_stress_Pa"] - 1, ls, color=c, lw=lw,
                         label=f"phi = {ph:g}: {what}/true - 1")
    ax1.set(xlabel="rim shear rate [1/s]", ylabel="shear stress [Pa]")
    ax1.set_title("parallel plate: true, apparent, corrected", fontsize=10)
    ax2.set(xlabel="rim shear rate [1/s]", ylabel="relative difference [-]")
    ax2.set_title("apparent and corrected against true", fontsize=10)
    _finish(fig, (ax1, ax2), title, 6)
    return fig


#: SI units in axis labels and their Table 1 (normalised) counterparts, longest first
_NORMALISED = (("[Pa s]", "[eta0]"), ("[1/s]", "[gdot0]"), ("[Pa]", "[eta0 gdot0]"),
               ("[s]", "[1/gdot0]"), ("[Hz]", "[gdot0]"), ("[N m]", "[-]"))


def normalise_units(fig) -> None:
    """Relabel a figure of a normalised (Table 1) material: SI units in axis labels and titles
    become the paper's units (stresses in eta0 gdot0, rates in gdot0, times in 1/gdot0)."""
    def fix(text: str) -> str:
        for si, norm in _NORMALISED:
            text = text.replace(si, norm)
        return text

    for ax in fig.axes:
        ax.set_xlabel(fix(ax.get_xlabel()))
        ax.set_ylabel(fix(ax.get_ylabel()))
        ax.set_title(fix(ax.get_title()))


def mark_ends(fig, ends) -> None:
    """Mark where runs ended early (:class:`rheology.run_end.RunEnd`, at the time of the last
    row written) on every time axis of ``fig``: a dashed line and the end's label."""
    for ax in fig.axes:
        if not ax.get_xlabel().startswith("time"):
            continue
        for end in ends:
            if end.time_s is not None and (end.time_s > 0 or ax.get_xscale() != "log"):
                mark_end(ax, end.time_s, f"ended: {end.label}")
