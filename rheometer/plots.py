"""Figures of the rheometer's results (matplotlib, Agg backend), written atomically."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

import rheology  # noqa: E402


def _colors(n: int):
    return plt.cm.viridis(np.linspace(0.0, 0.85, max(n, 1)))


def _positive(x):
    x = np.asarray(x, dtype=float)
    return np.where(x > 0, x, np.nan)


def flow_curve_figure(df: pd.DataFrame, material, title: str | None = None):
    """Two panels: shear stress vs shear rate and viscosity vs shear stress (log-log), one curve
    per phi; for rate or mixture-stress control the states as markers (crosses: unstable) over
    the whole steady curve (thin line); gdot_DST of Eq. (33) marked where DST exists."""
    m = rheology.get_material(material)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.4))
    phis = np.unique(df["phi"])
    for c, ph in zip(_colors(len(phis)), phis):
        d = df[df["phi"] == ph]
        label = f"phi = {ph:g}"
        if "stable" in d.columns:
            full = rheology.steady_state_stress(np.logspace(-3, 4, 300), ph, m)  # whole S-curve
            ax1.loglog(_positive(full.shear_rate), full.shear_stress, "-", color=c, lw=0.8,
                       alpha=0.5)
            for stable, style in ((True, "o"), (False, "x")):
                s = d[d["stable"] == stable]
                if len(s):
                    ax1.loglog(s["shear_rate_per_s"], s["shear_stress_Pa"], style, ms=3.5,
                               color=c, mfc=c if stable else "none",
                               label=label + ("" if stable else " (unstable)"))
                    ax2.loglog(s["shear_stress_Pa"], s["viscosity_Pa_s"], style, ms=3.5,
                               color=c, mfc=c if stable else "none")
        else:
            d = d.sort_values("granular_shear_stress_Pa")
            ax1.loglog(_positive(d["shear_rate_per_s"]), d["shear_stress_Pa"], "-", color=c,
                       lw=2, label=label)
            ax2.loglog(d["shear_stress_Pa"], _positive(d["viscosity_Pa_s"]), "-", color=c, lw=2)
        if m.phi_c <= ph <= min(m.phi_star, m.phi_j) and m.varphi1 + m.varphi2 > 0:
            g = float(rheology.gdot_dst(ph, m))
            ax1.axvline(g, color=c, ls=":", lw=1)
    ax1.set_xlabel("shear rate [1/s]")
    ax1.set_ylabel("mixture shear stress [Pa]")
    ax1.set_title("flow curve (dotted: Eq. 33 DST rate)", fontsize=10)
    ax1.legend(fontsize=8)
    ax2.set_xlabel("mixture shear stress [Pa]")
    ax2.set_ylabel("viscosity [Pa s]")
    ax2.set_title("viscosity", fontsize=10)
    for ax in (ax1, ax2):
        ax.grid(True, which="both", alpha=0.25)
    ctrl = df.attrs.get("control", "stress")
    fig.suptitle(title or f"{m.name}: steady flow curves ({ctrl} control)", fontsize=11)
    fig.tight_layout()
    return fig


def transient_figure(frames: dict, title: str, log_time: bool = False):
    """Mixture (solid) and granular (dashed) shear stress, shear rate and plastic rate, and the
    structure f against time; one colour per entry of ``frames`` (label -> DataFrame)."""
    fig, axs = plt.subplots(1, 3, figsize=(13, 3.9))
    for c, (label, df) in zip(_colors(len(frames)), frames.items()):
        t = df["time_s"].to_numpy()
        if log_time:
            t = np.where(t > 0, t, np.nan)
        axs[0].plot(t, df["shear_stress_Pa"], "-", color=c, lw=2, label=label)
        axs[0].plot(t, df["granular_shear_stress_Pa"], "--", color=c, lw=1)
        axs[1].plot(t, df["shear_rate_per_s"], "-", color=c, lw=2, label=label)
        axs[1].plot(t, df["plastic_shear_rate_per_s"], "--", color=c, lw=1)
        axs[2].plot(t, df["f"], "-", color=c, lw=2, label=label)
    for ax, col in ((axs[0], "shear_stress_Pa"), (axs[1], "shear_rate_per_s")):
        v = np.concatenate([d[col].to_numpy()[d["time_s"].to_numpy() > 0] for d in frames.values()])
        if v.size and np.all(v > 0) and v.max() > 100 * v.min():
            ax.set_yscale("log")
    axs[0].set_ylabel("shear stress [Pa] (dashed: granular)")
    axs[1].set_ylabel("shear rate [1/s] (dashed: plastic)")
    axs[2].set_ylabel("structure f [-]")
    for ax in axs:
        ax.set_xlabel("time [s]")
        if log_time:
            ax.set_xscale("log")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def program_figure(df: pd.DataFrame, title: str):
    """Stress against rate (hysteresis loop, coloured by step) and the time series."""
    fig, axs = plt.subplots(1, 3, figsize=(14, 4.2))
    steps = np.unique(df["step"])
    labels = df.attrs.get("steps", [])
    ax = axs[0]
    for c, k in zip(_colors(len(steps)), steps):
        d = df[df["step"] == k]
        lab = labels[k - 1] if k - 1 < len(labels) else f"step {k}"
        g = _positive(d["shear_rate_per_s"])
        if np.any(np.isfinite(g)):
            ax.loglog(g, _positive(d["shear_stress_Pa"]), "-", color=c, lw=2, label=lab)
    ax.set_xlabel("shear rate [1/s]")
    ax.set_ylabel("mixture shear stress [Pa]")
    ax.set_title("stress vs rate (arrows of time: legend order)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.25)
    t = df["time_s"]
    axs[1].semilogy(t, _positive(df["shear_stress_Pa"]), "-", lw=2, label="mixture stress")
    axs[1].semilogy(t, _positive(df["shear_rate_per_s"]), "-", lw=1.5, label="shear rate [1/s]")
    axs[1].set_ylabel("stress [Pa] / rate [1/s]")
    axs[1].legend(fontsize=8)
    axs[2].plot(t, df["f"], "-", lw=2, color="C2")
    axs[2].set_ylabel("structure f [-]")
    for ax in axs[1:]:
        ax.set_xlabel("time [s]")
        ax.grid(True, alpha=0.3)
        for tb in df.groupby("step")["time_s"].min().to_numpy()[1:]:
            ax.axvline(tb, color="0.6", lw=0.8, ls=":")
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig


def material_point_figure(df: pd.DataFrame, title: str):
    """Granular shear stress and pressure, normal-stress differences, f and phi against time."""
    fig, axs = plt.subplots(1, 3, figsize=(13, 3.9))
    t = df["time_s"]
    axs[0].plot(t, df["shear_stress_Pa"], "-", lw=2, label="sigma_xy")
    axs[0].plot(t, df["granular_pressure_Pa"], "--", lw=1.5, label="pressure p")
    axs[0].set_ylabel("granular stress [Pa]")
    axs[0].legend(fontsize=8)
    axs[1].plot(t, df["N1_Pa"], "-", lw=1.5, label="N1 = s_xx - s_yy")
    axs[1].plot(t, df["N2_Pa"], "--", lw=1.5, label="N2 = s_yy - s_zz")
    axs[1].set_ylabel("normal-stress differences [Pa]")
    axs[1].legend(fontsize=8)
    axs[2].plot(t, df["f"], "-", lw=2, color="C2", label="f")
    axs[2].set_ylabel("structure f [-]")
    ax2 = axs[2].twinx()
    ax2.plot(t, df["phi"], ":", lw=1.5, color="C3", label="phi")
    ax2.set_ylabel("volume fraction phi [-]", color="C3")
    for ax in axs:
        ax.set_xlabel("time [s]")
        ax.grid(True, alpha=0.3)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    return fig
