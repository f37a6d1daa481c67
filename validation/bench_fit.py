"""Speed of the fitter: a 5-curve, 30-points-per-curve fit (a typical measured set).

The reference is one model evaluation (all 150 points through the mixture-stress steady state),
timed in the same process; the fit's cost is reported as wall time, number of model evaluations
and its ratio to one evaluation, with and without the profile-likelihood intervals. For
comparison, one evaluation through the general branch finder of rheology.steady
(steady_states_mixture_stress) is timed too. Target: the fit in under 5 s.

The relaxation fit (rheometer.relaxation_fit): two curves of Fig. 15's middle setting (phi = 0.52,
G = 1e4 Pa, K0 = 1, taubar0 = 1 kPa and 300 Pa); the reference is one model run (rheometer
relax at 1000 output times over the first curve's record), timed in the same process; the fit's
cost is its wall time, its number of model runs and their ratio.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

import rheology as r
from rheology.fit import FlowData, fit_flow_curves, mixture_steady_state, synthetic_table

from rheometer.protocols import relax
from rheometer.relaxation_fit import POINTS, fit_relaxation, synthetic_relaxation

from .framework import BenchResult, benchmark, timed
from .report import machine_description


@benchmark("rheology", "bench_fit_speed", "Fit: 5 curves x 30 points, time and model evaluations")
def fit_speed(out: Path, quick: bool) -> BenchResult:
    m = r.get_material("hermes2016")
    phis = m.phi_c + (m.phi_j - m.phi_c) * np.array([-0.6, -0.25, 0.15, 0.45, 0.75])
    data = FlowData.from_table(synthetic_table(m, phis, points=30, seed=5, artefacts=False))
    start = m.replace(phi_j=0.55, phi_c=0.42, a0=1.0, a_inf=1.1, tau_star=15.0, varphi1=5e3)
    t_eval, _, _ = timed(lambda: mixture_steady_state(data.stress, data.phi, m),
                        20 if quick else 200)
    t_ref, _, _ = timed(lambda: r.steady_states_mixture_stress(data.stress, data.phi, m),
                       1 if quick else 3)
    rows, targets = [], []
    for profile in (False, True):
        t, _, res = timed(lambda: fit_flow_curves(data, start, profile=profile), 1 if quick else 3)
        rows.append({"profile_intervals": profile, "points": int(data.stress.size),
                     "fit_s": t, "model_evaluations": res.n_evaluations,
                     "fit / one evaluation": t / t_eval,
                     "evaluation-equivalents per evaluation": t / t_eval / res.n_evaluations})
        targets.append((f"fit {'with' if profile else 'without'} profile intervals < 5 s",
                        f"{t:.2f} s, {res.n_evaluations} evaluations", t < 5.0))
    summary = (f"{machine_description()}. One model evaluation (150 points, numba Brent kernel, "
               f"mixture stress imposed): {t_eval * 1e3:.3f} ms median; the same through "
               f"rheology.steady.steady_states_mixture_stress: {t_ref * 1e3:.1f} ms "
               f"({t_ref / t_eval:.0f}x). Fits: " + "; ".join(
                   f"{'profile' if q['profile_intervals'] else 'Jacobian only'}: {q['fit_s']:.2f} s"
                   f" = {q['fit / one evaluation']:.0f} evaluation times for "
                   f"{q['model_evaluations']} evaluations" for q in rows))
    return BenchResult(summary=summary, rows=rows, targets=targets)


@benchmark("rheometer", "bench_fit_relaxation_speed",
           "Relaxation fit: 2 curves, time and model runs (rheometer relax)")
def fit_relaxation_speed(out: Path, quick: bool) -> BenchResult:
    m = r.get_material("hermes2016")
    curves = [synthetic_relaxation(m, 0.52, tau0, G=1e4, K0=1.0, offset=0.002, seed=k)
              for k, tau0 in enumerate((1e3, 300.0))]
    t_end = float(curves[0].time.max())
    t_run, _, _ = timed(lambda: relax(m, 0.52, 1e3, t_end, G=1e4, K0=1.0, points=POINTS),
                       3 if quick else 15)
    t_fit, _, res = timed(lambda: fit_relaxation(curves, m), 1 if quick else 3)
    rows = [{"curves": 2, "points": int(sum(c.time.size for c in curves)), "fit_s": t_fit,
             "model_runs": res.n_runs, "one_run_s": t_run, "fit / one run": t_fit / t_run,
             "run-equivalents per run": t_fit / t_run / res.n_runs}]
    summary = (f"{machine_description()}. One model run (rheometer relax, {POINTS} output times): "
               f"{t_run * 1e3:.1f} ms median; the 2-curve fit: {t_fit:.2f} s = "
               f"{t_fit / t_run:.0f} run times for {res.n_runs} runs (the rest is interpolation "
               f"and the optimiser)")
    return BenchResult(summary=summary, rows=rows,
                       targets=[("relaxation fit of 2 curves < 10 s", f"{t_fit:.2f} s",
                                 t_fit < 10.0)])
