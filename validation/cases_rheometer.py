"""Validation cases of the rheometer tier (0-D): Fig. 15, transient limits, the material point.

Fig. 15's relaxation after cessation (Eqs. 35-37) against exact properties of the equations;
start-up and creep ending on the steady states of :mod:`rheology.steady`; the Table 8 material
point in homogeneous simple shear (volume and pressure control) against Eqs. (1)-(2), (13), its
first-order convergence to the IDA solution of the same tensor law, and its step-size limits.

Scene choices the paper does not state: Fig. 15's initial stress is not given; we relax from the
steady state at taubar0 = 1 kPa (within the measured range, below the ~10 kPa of slip and
breakdown). There t(1/e) G = 7.3e3 Pa s at K0 = 1, so G = 1e3-1e4 Pa gives t(1/e) = 7-0.7 s;
the paper's "tens of seconds" at G ~ 10 kPa needs a softer skeleton or a start nearer the DST
limit. Transient moduli default to G = 1e4 Pa, K0 = 1 (the steady fits give none).
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

import rheology
from rheometer import creep, relax, simple_shear_point, startup, tensor_reference
from runkit.plotting import plt

from .framework import Verdict, case, save_figure

HERMES = "hermes2016"


# ---------------------------------------------------------------------------------- Fig. 15
@case("rheometer", "fig15_relaxation",
      "Fig. 15: stress relaxation after cessation at phi = 0.52 (Hermes 2016), varying G and K0")
def fig15_relaxation(out: Path, quick: bool) -> Verdict:
    m = rheology.get_material(HERMES)
    phi, tau0, t_end = 0.52, 1e3, 100.0
    Gs, K0s = [1e3, 1e4, 1e5], [0.0, 0.1, 1.0, 10.0]
    runs = {("G", G): relax(m, phi, tau0, t_end, G=G, K0=1.0, rtol=1e-9, points=400)
            for G in Gs}
    runs |= {("K0", K0): runs["G", 1e4] if K0 == 1.0 else
             relax(m, phi, tau0, t_end, G=1e4, K0=K0, rtol=1e-9, points=400) for K0 in K0s}
    st = rheology.steady_state_stress(tau0, phi, m)
    f0, gdot0 = float(st.f), float(st.shear_rate)
    eta = m.eta0 * float(rheology.granular_viscosity(phi, f0, m))
    f10 = float(rheology.steady_state_stress(10.0, phi, m).f)
    eta10 = m.eta0 * float(rheology.granular_viscosity(phi, f10, m))
    f_m = float(rheology.f_max(phi, m))

    # (a) initial slope d taubar/dt = -G gdot_p(taubar0, f0), from a quadratic fit of the output
    slope_err = 0.0
    for (kind, v), df in runs.items():
        G = v if kind == "G" else 1e4
        t, s = df["time_s"].to_numpy()[:5], df["shear_stress_Pa"].to_numpy()[:5]
        slope = np.polyfit(t, s, 2)[1]
        slope_err = max(slope_err, abs(slope / (-G * gdot0) - 1.0))
    # (b) K0 = 0: frozen structure, exact exponential with time eta/G
    d0 = runs[("K0", 0.0)]
    exact = tau0 * np.exp(-1e4 * d0["time_s"].to_numpy() / eta)
    exp_err = float(np.max(np.abs(d0["shear_stress_Pa"].to_numpy() - exact)) / tau0)

    # (c) relaxation time t(1/e) ~ 1/G at K0 = 1; (d) decreasing with K0
    def t_e(df):
        s = df["shear_stress_Pa"].to_numpy() / tau0
        return float(np.interp(-np.exp(-1.0), -s, df["time_s"].to_numpy()))

    tG = np.array([t_e(runs[("G", G)]) * G for G in Gs])
    scaling_spread = float(tG.max() / tG.min() - 1.0)
    tK = [t_e(runs[("K0", K0)]) for K0 in K0s]
    k0_monotone = bool(np.all(np.diff(tK) < 0))
    # (e) bounds, monotone decay, full relaxation below jamming
    worst_rise, worst_end, f_ok = 0.0, 0.0, True
    for df in runs.values():
        s = df["shear_stress_Pa"].to_numpy()
        worst_rise = max(worst_rise, float(np.max(np.diff(s)) / tau0))
        worst_end = max(worst_end, float(s[-1] / tau0))
        f = df["f"].to_numpy()
        f_ok &= bool(np.all((f >= 0) & (f <= f_m + 1e-12)))

    fig, axs = plt.subplots(2, 2, figsize=(11, 7.5), sharex=True)
    colors = plt.cm.viridis(np.linspace(0, 0.85, 4))
    for col, (kind, values) in enumerate((("G", Gs), ("K0", K0s))):
        for c, v in zip(colors, values):
            df = runs[(kind, v)]
            t = df["time_s"].to_numpy()
            lab = f"G = {v:g} Pa" if kind == "G" else f"K0 = {v:g}"
            axs[0, col].semilogx(t[1:], df["shear_stress_Pa"].to_numpy()[1:], color=c, lw=2,
                                 label=lab)
            axs[1, col].semilogx(t[1:], df["f"].to_numpy()[1:], color=c, lw=2, label=lab)
        axs[0, col].set_title(f"({'ab'[col]}) varying {kind} "
                              f"({'K0 = 1' if kind == 'G' else 'G = 1e4 Pa'})", fontsize=10)
    axs[0, 1].semilogx(d0["time_s"].to_numpy()[1:], exact[1:], "k:", lw=1.5,
                       label="K0 = 0 exact: exp(-G t/eta)")
    for ax in axs[0]:
        ax.set_ylabel("granular shear stress [Pa]")
    for ax in axs[1]:
        ax.set(xlabel="time after cessation [s]", ylabel="structure f [-]")
    for ax in axs.ravel():
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"Relaxation from the steady state at {tau0:g} Pa, phi = {phi}, {HERMES} "
                 f"(f0 = {f0:.4f}, gdot0 = {gdot0:.4f} 1/s)", fontsize=11)

    passed = (slope_err < 1e-4 and exp_err < 1e-7 and scaling_spread < 0.10 and k0_monotone
              and worst_rise <= 1e-9 and worst_end < 1e-3 and f_ok)
    return Verdict(
        criterion="initial slope = -G gdot_p(taubar0, f0) to 1e-4; K0 = 0 equals "
                  "taubar0 exp(-G t/eta) to 1e-7 of taubar0; t(1/e) G constant within 10% over "
                  "G = 1e3..1e5 Pa (K0 = 1); t(1/e) decreases with K0; taubar never rises "
                  "(1e-9), ends below 1e-3 taubar0; 0 <= f <= f_m",
        measured=f"slope error {slope_err:.1e}; exponential error {exp_err:.1e}; t(1/e) G "
                 f"spread {100 * scaling_spread:.1f}% ({', '.join(f'{x:.3g}' for x in tG)} Pa s); "
                 f"t(1/e) vs K0 {', '.join(f'{x:.3g} s' for x in tK)}; max rise "
                 f"{worst_rise:.1e}; end {worst_end:.1e}; f in bounds {f_ok}",
        passed=bool(passed), figures=[save_figure(fig, out, "fig15_relaxation.png", tight=True)],
        details=f"eta/G at K0 = 0, G = 1e4 Pa: {eta / 1e4:.4g} s. From the example "
                f"(taubar0 = 10 Pa) the relaxation time is eta/G = {eta10 / 1e4 * 1e3:.3g} ms: "
                f"tens of seconds need stresses near the DST limit.")


# ---------------------------------------------------------------------- long-time limits
@case("rheometer", "transient_long_time_limits",
      "Start-up and creep end on the steady states of the steady solver (incl. the DST range)")
def transient_long_time_limits(out: Path, quick: bool) -> Verdict:
    m = rheology.get_material(HERMES)
    G, K0 = 1e4, 1.0
    startups = [(0.45, 1.0), (0.50, 0.3), (0.52, 0.05)] if quick else \
        [(0.44, 3.0), (0.45, 1.0), (0.48, 0.5), (0.50, 0.3), (0.50, 0.7), (0.52, 0.05),
         (0.52, 0.12)]
    creeps = [(0.52, 1.0), (0.52, 10.0)] if quick else \
        [(0.48, 10.0), (0.50, 1.0), (0.50, 30.0), (0.52, 0.5), (0.52, 3.0), (0.52, 10.0),
         (0.52, 100.0), (0.52, 1000.0)]
    rows, worst = [], 0.0
    for phi, rate in startups:
        df = startup(m, phi, rate, 60.0 / (K0 * rate), G=G, K0=K0, rtol=1e-9)
        end = df.iloc[-1]
        ss = rheology.steady_state_stress(end["granular_shear_stress_Pa"], phi, m)
        e_rate = abs(float(ss.shear_rate) / rate - 1.0)
        e_f = abs(float(ss.f) - end["f"]) / max(float(ss.f), 1e-12)
        lo, hi = rheology.steady_state_stress(end["granular_shear_stress_Pa"] * np.array(
            [1 - 1e-4, 1 + 1e-4]), phi, m).shear_rate
        stable = bool(hi > lo)                  # d gdot/d taubar > 0: stable under rate control
        worst = max(worst, e_rate, e_f) if stable else np.inf
        rows.append(("start-up", phi, rate, end["shear_stress_Pa"], e_rate, e_f, stable))
    for phi, tau in creeps:
        gd = float(rheology.steady_state_stress(tau, phi, m).shear_rate)    # time scale only
        df = creep(m, phi, tau, 60.0 / (K0 * gd), G=G, K0=K0, rtol=1e-9)
        end = df.iloc[-1]
        ss = rheology.steady_state_stress(end["granular_shear_stress_Pa"], phi, m)
        e_tau = abs(float(ss.shear_stress) / tau - 1.0)
        e_rate = abs(float(ss.shear_rate) / end["shear_rate_per_s"] - 1.0)
        e_f = abs(float(ss.f) - end["f"]) / max(float(ss.f), 1e-12)
        worst = max(worst, e_tau, e_rate, e_f)
        rows.append(("creep", phi, end["shear_rate_per_s"], tau, max(e_tau, e_rate), e_f, True))

    fig, ax = plt.subplots(figsize=(7.5, 5.2))
    phis = sorted({r[1] for r in rows})
    colors = dict(zip(phis, plt.cm.viridis(np.linspace(0, 0.85, len(phis)))))
    curve = rheology.steady_state_stress(np.logspace(-3, 4, 300)[None, :],
                                         np.array(phis)[:, None], m)
    for i, ph in enumerate(phis):
        ax.loglog(curve.shear_rate[i], curve.shear_stress[i], "-", color=colors[ph], lw=1.5,
                  label=f"steady, phi = {ph:g}")
    for kind, ph, g, tau, *_ in rows:
        ax.loglog(g, tau, "o" if kind == "start-up" else "s", color=colors[ph], mfc="none",
                  ms=9, mew=2)
    ax.plot([], [], "ko", mfc="none", label="start-up end state (imposed rate)")
    ax.plot([], [], "ks", mfc="none", label="creep end state (imposed mixture stress)")
    ax.set(xlabel="shear rate [1/s]", ylabel="mixture shear stress [Pa]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    ax.set_title(f"{HERMES}: transients (IDA, 60 structure times) end on the steady curves",
                 fontsize=10)
    png = save_figure(fig, out, "long_time_limits.png", tight=True)
    table = "\n".join(f"{k:8s} phi={ph:<5g} rate={g:<9.4g} tau={tau:<9.4g} rel.err(rate/stress)="
                      f"{er:.1e} rel.err(f)={ef:.1e} stable={s}" for k, ph, g, tau, er, ef, s
                      in rows)
    return Verdict(
        criterion="end state of every start-up (stable rates) and creep (mixture stresses, "
                  "including the decreasing DST part at phi = 0.52) matches the steady solver's "
                  "state at its granular stress: rate, stress and f within 1e-6 relative; "
                  "start-up end states on a stable branch",
        measured=f"worst relative deviation {worst:.1e} over {len(rows)} transients",
        passed=bool(worst < 1e-6), figures=[png], details=table)


# ---------------------------------------------------------------------- material point
@functools.lru_cache(maxsize=64)
def _steady_point(name: str, phi: float, rate: float):
    """(granular stress, pressure) of the lowest stable steady state of material ``name``."""
    ss = rheology.steady_states_rate(rate, phi, rheology.get_material(name))
    i = int(np.flatnonzero(ss.stable)[0])
    return float(ss.taubar[i]), float(ss.pressure[i])


@case("rheometer", "material_point_steady_state",
      "Material point: steady simple shear of the Table 8 local update reproduces Eq. (1)-(2)")
def material_point_steady_state(out: Path, quick: bool) -> Verdict:
    m = rheology.get_material(HERMES)
    K0 = 1.0
    cases = [(0.45, 1.0, "volume"), (0.52, 0.05, "volume"), (0.50, 0.5, "pressure")] if quick \
        else [(0.40, 3.0, "volume"), (0.45, 1.0, "volume"), (0.50, 0.5, "volume"),
              (0.52, 0.05, "volume"), (0.45, 1.0, "pressure"), (0.50, 0.5, "pressure")]
    rows, worst = [], 0.0
    for phi, rate, ctrl in cases:
        tau_ss, p_ss = _steady_point(m.name, float(phi), float(rate))
        # G = 1e6 Pa for volume control (the Jaumann normal-stress error ~(taubar/G)^2 is
        # ~1e-12); 1e4 Pa under pressure control, whose step must stay below p/(K |dphi/dt|)
        G = 1e6 if ctrl == "volume" else 1e4
        kw = dict(G=G, K0=K0, stress0=0.5 * tau_ss)
        phi0, dt = phi, min(1e-2, 0.01 / rate)
        if ctrl == "pressure":                     # start looser; phi must compact to phi
            kw.update(control="pressure", pressure=p_ss)
            phi0, dt = phi - 0.005, 1e-3
        t_end = 40.0 / (K0 * rate)
        df = simple_shear_point(m, phi0, rate, t_end, dt, points=200, **kw)
        end = df.iloc[-1]
        ph, f = float(end["phi"]), float(end["f"])
        eq1 = float(rheology.granular_viscosity(ph, f, m))
        eq2 = float(rheology.normal_viscosity(ph, f, m))
        eta_s = end["shear_stress_Pa"] / (m.eta0 * rate)
        eta_n = end["granular_pressure_Pa"] / (m.eta0 * rate)
        f13 = float(rheology.steady_state_stress(end["granular_shear_stress_Pa"], ph, m).f)
        errs = (abs(eta_s / eq1 - 1), abs(eta_n / eq2 - 1), abs(f / f13 - 1))
        worst = max(worst, *errs)
        rows.append((ctrl, phi0, ph, rate, eta_s, eq1, eta_n, eq2, *errs))

    fig, ax = plt.subplots(figsize=(7, 5))
    for i, (ctrl, phi0, ph, rate, es, e1, en, e2, *_e) in enumerate(rows):
        ax.loglog(e1, es, "o" if ctrl == "volume" else "s", color="C0", ms=8,
                  label="shear: sigma_xy/(eta0 gdot) vs Eq. (1)" if i == 0 else None)
        ax.loglog(e2, en, "o" if ctrl == "volume" else "s", color="C1", ms=8,
                  label="normal: p/(eta0 gdot) vs Eq. (2)" if i == 0 else None)
    lim = np.array([min(r[5] for r in rows) * 0.5, max(r[7] for r in rows) * 2])
    ax.loglog(lim, lim, "k:", lw=1, label="equality")
    ax.set(xlabel="Eq. (1) granular part / Eq. (2) at the end state's phi, f",
           ylabel="material point at steady state")
    ax.set_title("circles: volume control; squares: pressure control (G = 1e6 Pa)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    png = save_figure(fig, out, "material_point_steady.png", tight=True)
    details = "\n".join(f"{c:8s} phi0={p0:<6g} phi_end={ph:.6f} gdot={g:<5g} eta_s={es:.8g} "
                        f"(Eq.1 {e1:.8g}) eta_n={en:.8g} (Eq.2 {e2:.8g}) errors {a:.1e} {b:.1e} "
                        f"{c2:.1e}" for c, p0, ph, g, es, e1, en, e2, a, b, c2 in rows)
    return Verdict(
        criterion="at steady state sigma_xy/(eta0 gdot) = Eq. (1) granular part, p/(eta0 gdot) "
                  "= Eq. (2), f = Eq. (13) at the end state's phi and f, each within 1e-6 "
                  "relative (the Jaumann normal stresses perturb sigma_xy by O((taubar/G)^2); "
                  "G = 1e6 Pa under volume control, 1e4 Pa under pressure control)",
        measured=f"worst relative error {worst:.1e} over {len(rows)} runs",
        passed=bool(worst < 1e-6), figures=[png], details=details)


CONVERGENCE_SCENARIOS = (("volume", 2.0), ("volume", 0.5), ("pressure", 2.0), ("pressure", 0.5))


def convergence_study(scenarios=CONVERGENCE_SCENARIOS, levels=range(5, 14), T: float = 2.0):
    """Errors of the material point against the IDA tensor reference for dt = T/2^k.

    Phi = 0.50, Hermes 2016, G = 100 Pa (elastic time ~ 20 ms, resolved), K = (8.3/3.8) G,
    K0 = 1; start from the steady state at taubar = 1 Pa, then the rate is multiplied by the
    scenario's factor (2: dilatant shear flow; 0.5: compaction, and under pressure control a
    switch back to dilatant flow). Error: max over 17 common times of the relative error in
    sigma_xy, p, f and phi. Returns {scenario: (dts, errors, reference, coarse run)}.
    """
    m = rheology.get_material(HERMES)
    phi, tau0 = 0.50, 1.0
    st = rheology.steady_state_stress(tau0, phi, m)
    g0 = float(st.shear_rate)
    times = np.linspace(0.0, T, 17)
    results = {}
    for ctrl, factor in scenarios:
        kw = dict(G=100.0, K0=1.0, stress0=tau0)
        if ctrl == "pressure":
            kw.update(control="pressure", pressure=float(st.pressure))
        ref = tensor_reference(m, phi, factor * g0, T, times=times, **kw)
        dts, errs, coarse = [], [], None
        for k in levels:
            dt = T / 2 ** k
            mp = simple_shear_point(m, phi, factor * g0, T, dt, points=16, **kw)
            e = max(float(np.max(np.abs(mp[c].to_numpy() - ref[c].to_numpy()))
                          / np.max(np.abs(ref[c].to_numpy())))
                    for c in ("shear_stress_Pa", "granular_pressure_Pa", "f", "phi"))
            dts.append(dt)
            errs.append(e)
            coarse = mp if coarse is None else coarse
        results[(ctrl, factor)] = (np.array(dts), np.array(errs), ref, coarse)
    return results


@case("rheometer", "material_point_convergence",
      "Material point: first-order convergence in dt to the IDA solution of the same tensor law")
def material_point_convergence(out: Path, quick: bool) -> Verdict:
    res = convergence_study(levels=range(8, 13) if quick else range(5, 14))
    orders, ok = {}, True
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(12, 4.6))
    for (ctrl, fac), (dts, errs, ref, coarse) in res.items():
        o = np.log2(errs[:-1] / errs[1:])
        tail = o[-4:]
        orders[(ctrl, fac)] = tail
        ok &= bool(np.all(tail > 0.9) and np.all(tail < 1.3))
        ax.loglog(dts, errs, "o-", label=f"{ctrl} control, rate x{fac:g} "
                                         f"(last orders {', '.join(f'{x:.2f}' for x in tail)})")
    dts = next(iter(res.values()))[0]
    ax.loglog(dts, 0.5 * dts / dts[0] * max(e[1][0] for e in res.values()), "k:",
              label="slope 1")
    ax.set(xlabel="time step dt [s]", ylabel="max relative error vs IDA (sigma_xy, p, f, phi)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    dts_, errs_, ref, coarse = res[("pressure", 0.5)]
    ax2.plot(ref["time_s"], ref["phi"], "k-", lw=2, label="IDA tensor reference")
    ax2.plot(coarse["time_s"], coarse["phi"], "o--", ms=4,
             label=f"material point dt = {dts_[0]:.3g} s")
    for t, what in ref.attrs.get("switches", []):
        ax2.axvline(t, color="C3", ls=":", lw=1)
        ax2.text(t, ax2.get_ylim()[0], f" -> {what}", color="C3", fontsize=7, va="bottom")
    ax2.set(xlabel="time [s]", ylabel="volume fraction phi")
    ax2.set_title("pressure control, rate halved: compaction, then dilatant flow", fontsize=9)
    ax2.grid(True, alpha=0.3)
    ax2.legend(fontsize=8)
    return Verdict(
        criterion="observed order log2(e(dt)/e(dt/2)) between 0.9 and 1.3 over the 4 finest "
                  "halvings, in all four scenarios (volume/pressure control, rate up/down, "
                  "including a compaction -> dilatant regime switch)",
        measured="; ".join(f"{c} x{f:g}: {', '.join(f'{x:.3f}' for x in o)}"
                           for (c, f), o in orders.items()),
        passed=ok, figures=[save_figure(fig, out, "material_point_convergence.png", tight=True)],
        details="\n".join(f"{c} x{f:g}: dt {', '.join(f'{d:.2e}' for d in v[0])}\n    errors "
                          f"{', '.join(f'{e:.2e}' for e in v[1])}"
                          for (c, f), v in res.items()))


def _classify(m, phi, rate, K0, dt, ctrl) -> str:
    """'ok', 'inaccurate' (> 10% from the steady state, or oscillating), 'garbage' (non-finite,
    or f outside [0, 1]) or 'failed' (RuntimeError) of a run at step ``dt``."""
    tau_ss, p_ss = _steady_point(m.name, float(phi), float(rate))
    kw = dict(G=1e4, K0=K0, stress0=0.5 * tau_ss)
    if ctrl == "pressure":
        kw.update(control="pressure", pressure=p_ss)
    T = max(20.0 / (K0 * rate), 20 * dt)
    n = int(round(T / dt))
    try:
        df = simple_shear_point(m, phi, rate, n * dt, dt, points=min(n, 200), **kw)
    except RuntimeError:
        return "failed"
    s = df["shear_stress_Pa"].to_numpy()
    finite = bool(np.all(np.isfinite(s)) and np.all((df["f"] >= 0) & (df["f"] <= 1)))
    if not finite:
        return "garbage"
    late = np.diff(s[len(s) // 2:])
    sig = np.sign(late[np.abs(late) > 1e-6 * np.abs(s).max()])
    flips = int(np.sum(sig[1:] != sig[:-1])) if sig.size > 1 else 0
    err = abs(s[-1] - tau_ss) / abs(tau_ss)
    return "ok" if (err < 0.1 and flips <= 2) else "inaccurate"


@case("rheometer", "material_point_stability",
      "Material point: step-size limits (volume control stable; pressure control solvable)")
def material_point_stability(out: Path, quick: bool) -> Verdict:
    m = rheology.get_material(HERMES)
    dts = [1e-3, 1e-2, 0.1, 1.0] if quick else [1e-3, 3e-3, 1e-2, 3e-2, 0.1, 0.3, 1.0, 3.0,
                                                  30.0, 300.0]
    configs = [(0.45, 1.0, 1.0), (0.52, 0.1, 1.0)] if quick else \
        [(0.45, 1.0, 0.1), (0.45, 1.0, 1.0), (0.45, 1.0, 10.0), (0.50, 0.5, 1.0),
         (0.52, 0.1, 1.0), (0.52, 0.1, 10.0)]
    grid, labels = [], []
    garbage, vol_ok, contiguous = 0, True, True
    for ctrl in ("volume", "pressure"):
        for phi, rate, K0 in configs:
            row = [_classify(m, phi, rate, K0, dt, ctrl) for dt in dts]
            garbage += row.count("garbage")
            if ctrl == "volume":
                vol_ok &= all(c == "ok" for c in row)
            bad = [i for i, c in enumerate(row) if c != "ok"]
            contiguous &= all(row[i] != "ok" for i in range(bad[0], len(row))) if bad else True
            grid.append(row)
            labels.append(f"{ctrl}: phi {phi:g}, gdot {rate:g} 1/s, K0 {K0:g}")
    fig, ax = plt.subplots(figsize=(9, 0.45 * len(grid) + 1.6))
    style = {"ok": ("o", "C2"), "inaccurate": ("^", "C1"), "failed": ("x", "C3"),
             "garbage": ("*", "k")}
    for i, row in enumerate(grid):
        for j, c in enumerate(row):
            mk, col = style[c]
            ax.plot(dts[j], i, mk, color=col, ms=9, mew=2)
    for name, (mk, col) in style.items():
        ax.plot([], [], mk, color=col, label=name + (" (RuntimeError raised)" if name == "failed"
                                                      else ""))
    ax.set_xscale("log")
    ax.set_yticks(range(len(grid)), labels, fontsize=7)
    ax.set_xlabel("time step dt [s] (G = 1e4 Pa, K = 2.18e4 Pa, hermes2016)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.0, 1.0))
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_title("material-point step-size map (each dt split into sub-steps within the spin "
                 "and cancellation bounds)", fontsize=9)
    png = save_figure(fig, out, "material_point_stability.png", tight=True)
    details = "\n".join(f"{lab}: " + " ".join(f"{d:g}:{c}" for d, c in zip(dts, row))
                        for lab, row in zip(labels, grid))
    return Verdict(
        criterion="no run returns non-finite or out-of-range data (a failing solve raises); "
                  "volume control is stable and within 10% of its steady state at every dt up to "
                  f"{dts[-1]:g} s; under pressure control the successful step sizes form one "
                  "interval from the smallest dt (a clear boundary)",
        measured=f"garbage runs {garbage}; volume control all ok: {vol_ok}; contiguous "
                 f"boundaries: {contiguous}",
        passed=bool(garbage == 0 and vol_ok and contiguous), figures=[png], details=details)
