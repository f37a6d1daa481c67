"""Speed of the fitter: a 5-curve, 30-points-per-curve fit (the issue's size).

The reference is one model evaluation (all 150 points through the mixture-stress steady state),
timed in the same process; the fit's cost is reported as wall time, number of model evaluations
and its ratio to one evaluation, with and without the profile-likelihood intervals. For
comparison, one evaluation through the general branch finder of rheology.steady
(steady_states_mixture_stress) is timed too. Target: the fit in under 5 s.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

import rheology as r
from rheology.fit import FlowData, fit_flow_curves, mixture_steady_state, synthetic_table

from .framework import BenchResult, benchmark
from .report import machine_description


def _median(fn, repeats):
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts)), out


@benchmark("rheology", "bench_fit_speed", "Fit: 5 curves x 30 points, time and model evaluations")
def fit_speed(out: Path, quick: bool) -> BenchResult:
    m = r.get_material("hermes2016")
    phis = m.phi_c + (m.phi_j - m.phi_c) * np.array([-0.6, -0.25, 0.15, 0.45, 0.75])
    data = FlowData.from_table(synthetic_table(m, phis, points=30, seed=5, artefacts=False))
    start = m.replace(phi_j=0.55, phi_c=0.42, a0=1.0, a_inf=1.1, tau_star=15.0, varphi1=5e3)
    t_eval, _ = _median(lambda: mixture_steady_state(data.stress, data.phi, m), 20 if quick else 200)
    t_ref, _ = _median(lambda: r.steady_states_mixture_stress(data.stress, data.phi, m),
                       1 if quick else 3)
    rows, targets = [], []
    for profile in (False, True):
        t, res = _median(lambda: fit_flow_curves(data, start, profile=profile), 1 if quick else 3)
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
