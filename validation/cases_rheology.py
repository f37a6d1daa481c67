"""Validation of the shared constitutive module against the paper's steady relations and figures.

The paper's figure data are not available to us, so each case checks what the figure shows as
falsifiable properties of the model curves: Eq. (13) satisfied to 1e-10, the low- and high-stress
limit laws (Eqs. 24-25), the DST limit (Eq. 33), which volume fractions jam or turn S-shaped, and
the local update driven through simple shear landing on Eqs. (1)-(2).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import rheology as r
from rheology.local_update import NOUT, kernel_parameters, update_points_serial
from runkit.plotting import plt

from .framework import Verdict, case, save_figure

FIG1_PHI = (0.45, 0.50, 0.54, 0.56, 0.57, 0.58, 0.60, 0.62, 0.63, 0.64)


def eq13_residual(flow, m) -> float:
    """Largest relative residual of Eq. (13) over the flowing points of a SteadyFlow."""
    ok = ~flow.jammed & (flow.shear_rate > 0) & (flow.f > 0)
    H = r.hardening(flow.taubar[ok], m)
    S = r.softening(flow.taubar[ok], flow.shear_rate[ok], flow.phi[ok], m)
    fm = r.f_max(flow.phi[ok], m)
    return float(np.max(np.abs(flow.f[ok] - H * fm / (H + S)) / flow.f[ok], initial=0.0))


def _colours(n):
    return plt.cm.viridis(np.linspace(0, 0.9, n))


def limit_errors(phi, m, high: bool) -> tuple[float, float]:
    """Relative errors of the steady viscosity at 1e-8 tau* against Eq. (24) and (``high``) at
    1e14 tau* against Eq. (25) (0 when not ``high``)."""
    low = r.steady_state_stress(1e-8 * m.tau_star, phi, m)
    lo = abs(low.viscosity / m.eta0 / r.viscosity_low_limit(phi, m) - 1)
    if not high:
        return float(lo), 0.0
    top = r.steady_state_stress(1e14 * m.tau_star, phi, m)
    return float(lo), float(abs(top.viscosity / m.eta0 / r.viscosity_high_limit(phi, m) - 1))


@case("rheology", "fig1_singh_model_curves",
      "Fig. 1: steady curves of Table 1 (a) and (b) at the caption's volume fractions")
def fig1(out: Path, quick: bool) -> Verdict:
    taus = np.logspace(-3, 5, 200 if quick else 1200)
    fig, ax = plt.subplots(figsize=(6, 4.5))
    res, lo_err, hi_err, rows = 0.0, 0.0, 0.0, []
    jams, sshape = {}, {}
    for fit, ls, colour in (("a", "--", "tab:red"), ("b", "-", "tab:blue")):
        m = r.get_material(f"singh2018_{fit}")
        for phi in FIG1_PHI:
            flow = r.steady_state_stress(taus * m.tau_star, phi, m)
            res = max(res, eq13_residual(flow, m))
            flowing = ~flow.jammed
            jams[fit, phi] = bool(flow.jammed.any())
            sshape[fit, phi] = bool(np.any(np.diff(flow.shear_rate[flowing]) < 0))
            ax.loglog(flow.shear_stress[flowing], flow.shear_rate[flowing], ls, color=colour,
                      lw=1)
            lo, hi = limit_errors(phi, m, high=phi < m.phi_c and fit == "b")
            lo_err, hi_err = max(lo_err, lo), max(hi_err, hi)
            rows.append(f"fit ({fit}) phi = {phi:.2f}: {'jams' if jams[fit, phi] else 'flows'}, "
                        f"{'S-shaped' if sshape[fit, phi] else 'monotone'}, "
                        f"max gdot/gdot0 = {flow.shear_rate.max():.3g}")
    ax.set(xlabel=r"$\tau/(\eta_0\dot\gamma_0)$", ylabel=r"$\dot\gamma/\dot\gamma_0$",
           title="Table 1 fits: (a) red dashed, (b) blue solid", ylim=(1e-6, 1e4))
    phi_c = r.get_material("singh2018_a").phi_c
    jam_ok = (all(jams["a", p] == (p > phi_c) for p in FIG1_PHI)
              and not any(jams["b", p] for p in FIG1_PHI))
    s_ok = all(sshape["b", p] == (p > phi_c) for p in FIG1_PHI)
    passed = res <= 1e-10 and lo_err <= 1e-6 and hi_err <= 1e-3 and jam_ok and s_ok
    return Verdict(
        criterion="Eq. 13 residual <= 1e-10; low-stress viscosity = Eq. 24 to 1e-6; fit (b) high-"
                  "stress viscosity = Eq. 25 to 1e-3 below phi_c; fit (a) (eta_B = inf) jams exactly "
                  "for phi > phi_c; fit (b) never jams and is S-shaped exactly for phi > phi_c",
        measured=f"Eq. 13 {res:.1e}; Eq. 24 {lo_err:.1e}; Eq. 25 {hi_err:.1e}; jamming pattern "
                 f"{'as stated' if jam_ok else 'DIFFERENT'}; S-shape pattern "
                 f"{'as stated' if s_ok else 'DIFFERENT'}",
        passed=passed, figures=[save_figure(fig, out, "fig1.png")], details="\n".join(rows))


def fig2_phis(m) -> np.ndarray:
    """Volume fractions drawn for a Fig. 2 material: two CST, three DST (legends not in the text)."""
    return np.array([0.85 * m.phi_c, 0.95 * m.phi_c, m.phi_c + 0.25 * (m.phi_j - m.phi_c),
                     m.phi_c + 0.5 * (m.phi_j - m.phi_c), m.phi_c + 0.75 * (m.phi_j - m.phi_c)])


@case("rheology", "fig2_experimental_fits",
      "Fig. 2: steady curves of the six experimental fits (Tables 2-3)")
def fig2(out: Path, quick: bool) -> Verdict:
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    res, lo_err, hi_err, dst_err, rows = 0.0, 0.0, 0.0, 0.0, []
    for ax, name, panel in zip(axes.flat, r.FIG2_MATERIALS, "abcdef"):
        m = r.get_material(name)
        taus = np.logspace(-3, 5, 150 if quick else 600) * m.tau_star
        phis = fig2_phis(m)
        extra = [0.39] if name == "hermes2016" else []
        for phi, colour in zip(list(phis) + extra, list(_colours(len(phis))) + ["tab:red"]):
            flow = r.steady_state_stress(taus, phi, m)
            res = max(res, eq13_residual(flow, m))
            ax.loglog(flow.shear_stress, flow.viscosity, "--" if phi in extra else "-",
                      color=colour, label=f"$\\phi$ = {phi:.3f}")
            lo, hi = limit_errors(phi, m, high=phi < m.phi_c)
            lo_err, hi_err = max(lo_err, lo), max(hi_err, hi)
            if phi >= m.phi_c:
                g = r.steady_state_stress(1e12 * m.tau_star, phi, m).shear_rate
                e = abs(g / r.gdot_dst(phi, m) - 1)
                dst_err = max(dst_err, e)
                rows.append(f"{name} phi = {phi:.3f}: gdot(1e12 tau*) / gdot_DST - 1 = {e:.1e}")
        ax.set_title(f"({panel}) {name}", fontsize=10)
        ax.set(xlabel=r"mixture shear stress $\tau$ [Pa]",
               ylabel=r"viscosity $\tau/\dot\gamma$ [Pa s]")
        ax.set_ylim(top=min(ax.get_ylim()[1], 1e6))
        ax.legend(fontsize=7)
    return Verdict(
        criterion="Eq. 13 residual <= 1e-10; low-stress plateau = Eq. 24 to 1e-6; for phi < phi_c "
                  "the high-stress plateau = Eq. 25 to 1e-3; for phi_c <= phi < phi_j the rate at "
                  "1e12 tau* is within 1e-3 of gdot_DST (Eq. 33)",
        measured=f"Eq. 13 {res:.1e}; Eq. 24 {lo_err:.1e}; Eq. 25 {hi_err:.1e}; DST limit {dst_err:.1e}",
        passed=res <= 1e-10 and lo_err <= 1e-6 and hi_err <= 1e-3 and dst_err <= 1e-3,
        figures=[save_figure(fig, out, "fig2.png", tight=True)], details="\n".join(rows))


@case("rheology", "fig10_steady_structure",
      "Fig. 10: steady f(tau), Eq. (16), against the Wyart-Cates and Singh forms")
def fig10(out: Path, quick: bool) -> Verdict:
    x = np.logspace(-3, 3, 400)
    ours, wc, singh = r.steady_f_of_stress(x, 1.0), r.wyart_cates_f(x, 1.0), r.singh_f(x, 1.0)
    between = bool(np.all((singh <= ours) & (ours <= wc)))
    d_wc, d_singh = float(np.max(np.abs(ours - wc))), float(np.max(np.abs(ours - singh)))
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.semilogx(x, ours, "k-", label=r"Eq. (16): $H/(H+1)$, $H = (\tau/\tau^*)^{3/2}$")
    ax.semilogx(x, wc, "--", label=r"Wyart & Cates: $1 - e^{-\tau/\tau^*}$")
    ax.semilogx(x, singh, "-.", label=r"Singh et al.: $e^{-\tau^*/\tau}$")
    ax.set(xlabel=r"$\tau/\tau^*$", ylabel="f")
    ax.legend(fontsize=8)
    return Verdict(
        criterion="Eq. 16 lies between the Singh (below) and Wyart-Cates (above) forms for all "
                  "tau/tau* in [1e-3, 1e3]",
        measured=f"between everywhere: {between}; max |ours - WC| = {d_wc:.3f}, "
                 f"max |ours - Singh| = {d_singh:.3f}",
        passed=between, figures=[save_figure(fig, out, "fig10.png")])


@case("rheology", "gdot_dst_vs_eq33",
      "gdot_DST against phi: high-stress limit of the steady solver vs Eq. (33)")
def gdot_dst_case(out: Path, quick: bool) -> Verdict:
    fig, ax = plt.subplots(figsize=(6, 4.5))
    worst, rows = 0.0, []
    for name, colour in zip(r.FIG2_MATERIALS, _colours(6)):
        m = r.get_material(name)
        phis = m.phi_c + (m.phi_j - m.phi_c) * np.linspace(0.0, 0.97, 6 if quick else 15)
        g1, g4 = (r.steady_state_stress(t * m.tau_star, phis, m).shear_rate for t in (1e12, 4e12))
        limit = 2 * g4 - g1                      # removes the tau^-1/2 approach term
        eq33 = r.gdot_dst(phis, m)
        err = np.abs(limit / eq33 - 1)
        worst = max(worst, float(err.max()))
        rows.append(f"{name}: max |extrapolated / Eq. 33 - 1| = {err.max():.1e}")
        x = m.phi_j - phis
        ax.loglog(x, eq33, "-", color=colour, label=name)
        ax.loglog(x, limit, "o", color=colour, ms=4, mfc="none")
    ax.set(xlabel=r"$\phi_j - \phi$", ylabel=r"$\dot\gamma_{DST}$ [1/s]",
           title="lines: Eq. (33); circles: steady solver at high stress")
    ax.legend(fontsize=7)
    return Verdict(criterion="extrapolated high-stress rate equals Eq. 33 to 1e-6 relative for "
                             "phi_c <= phi < phi_j, six materials",
                   measured=f"max relative difference {worst:.1e}", passed=worst <= 1e-6,
                   figures=[save_figure(fig, out, "gdot_dst.png")], details="\n".join(rows))


@case("rheology", "local_update_steady_shear",
      "Table 8 local update driven through simple shear lands on Eqs. (1), (2), (13)")
def local_update_steady_shear(out: Path, quick: bool) -> Verdict:
    m = r.get_material("hermes2016", G=1e6, K=2e6, K0=1.0)
    P = kernel_parameters(m)
    phi, rates = 0.48, (0.01, 0.1, 1.0)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    worst, rows = 0.0, []
    for gdot, colour in zip(rates, _colours(3)):
        target = r.steady_states_rate(gdot, phi, m)
        nstep, dstrain = (4000, 0.01) if quick else (20000, 0.005)
        sig = -1e-3 * np.eye(3)[None].copy()
        L = np.zeros((1, 3, 3))
        L[0, 0, 1] = gdot
        ph, f = np.array([phi]), np.array([0.0])
        so, o = np.empty_like(sig), np.empty((1, NOUT))
        hist = np.empty((nstep, 3))
        for n in range(nstep):
            update_points_serial(sig, L, ph, f, dstrain / gdot, P, so, o)
            sig, f = so.copy(), o[:, 0].copy()
            hist[n] = (sig[0, 0, 1], o[0, 11], f[0])
        strain = dstrain * np.arange(1, nstep + 1)
        errs = np.abs(hist[-1] / [target.taubar[0], target.pressure[0], target.f[0]] - 1)
        worst = max(worst, float(errs.max()))
        rows.append(f"gdot = {gdot}: relative error (tau, p, f) = " + ", ".join(f"{e:.1e}" for e in errs))
        axes[0].loglog(strain, hist[:, 0], color=colour, label=fr"$\dot\gamma$ = {gdot} 1/s")
        axes[0].axhline(target.taubar[0], color=colour, ls=":")
        axes[1].semilogx(strain, hist[:, 2], color=colour)
        axes[1].axhline(target.f[0], color=colour, ls=":")
    axes[0].set(xlabel="strain", ylabel=r"$\sigma_{xy}$ [Pa] (dotted: Eq. 1)")
    axes[1].set(xlabel="strain", ylabel="f (dotted: Eq. 13)")
    axes[0].legend(fontsize=8)
    fig.suptitle(f"Hermes 2016, phi = {phi}, G = 1 MPa, K = 2 MPa, K0 = 1")
    png = save_figure(fig, out, "local_update_steady_shear.png")
    tol = 1e-6 if quick else 1e-8
    return Verdict(criterion=f"shear stress, pressure and f at steady state equal Eqs. (1), (2), "
                             f"(13) to {tol:g} relative at three rates",
                   measured=f"max relative error {worst:.1e}", passed=worst <= tol,
                   figures=[png], details="\n".join(rows))
