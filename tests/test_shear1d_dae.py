"""Method "dae" of shear1d: the reduced (critical-state) law as a smooth DAE (shear1d.dae).

Physics asserted: the Newtonian limit of the slow Fig. 3 case (v = A r + B/r), the steady state
of a stress-driven plane Couette cell against rheology's steady flow curve (the reduced law's
fixed point is Eq. 13 with the critical state), the fast Fig. 3 front against the explicit
full-law method (a stated, measured difference: the reduced law has no pressure dynamics), the
Jacobian's band, resume, and refusal of the two-phase mode. The cost against cell count is a
benchmark (validation/bench_shear1d.py, shear1d_cost_vs_cells), not a timed test.
"""

from __future__ import annotations

import numpy as np
import pytest

import rheology
from shear1d.analytic import annular_steady
from shear1d.cli import main as cli_main
from shear1d.dae import BANDWIDTH, ReducedDAE
from shear1d.integrate import solve
from shear1d.scenes import annular_shear_jamming, plane_couette, summarize

SLOW, FAST = 0.84e-3, 84e-3


def test_newtonian_limit_slow_annular():
    """u_i = 0.84 mm/s: f stays ~0, the profile reaches the steady Newtonian A r + B/r."""
    pb, t_end = annular_shear_jamming(SLOW, n_cells=30)
    res = solve(pb, t_end, method="dae", n_out=10)
    g = pb.grid
    v = res.field("v")[-1]
    dev = np.max(np.abs(v - annular_steady(g.faces, g.inner, g.outer, SLOW))) / SLOW
    assert dev < 0.005                                   # measured 8.9e-4 (full law: 8.9e-4)
    assert res.field("f").max() < 0.01 * float(rheology.f_jam(pb.phi0, pb.material))
    # same answer as the full-law IDA method where the laws coincide (no jamming)
    ref = solve(pb, t_end, method="ida", n_out=10)
    assert np.max(np.abs(ref.field("v")[-1] - v)) / SLOW < 1e-3


def test_stress_driven_steady_state_is_the_flow_curve():
    """Plane Couette pushed by the mixture stress of rheology's steady state at taubar = 5 Pa:
    uniform rate, structure and pressure reach the steady flow curve's (Eq. 13)."""
    m = rheology.get_material("annular_shear")
    st = rheology.steady_state_stress(5.0, m.phi0, m)
    gap = 1e-3
    pb = plane_couette(stress=float(st.shear_stress), gap=gap, n_cells=8)
    res = solve(pb, 100.0, method="dae", n_out=5)
    gdot = res.field("v")[-1][0] / gap
    assert gdot == pytest.approx(float(st.shear_rate), rel=5e-3)     # measured 1.4e-3
    assert res.field("f")[-1] == pytest.approx(float(st.f), rel=5e-3)
    assert res.field("pressure")[-1] == pytest.approx(float(st.pressure), rel=5e-3)
    assert np.abs(res.field("sigma_rth")[-1]) == pytest.approx(5.0, rel=1e-3)


def test_fast_front_against_explicit_full_law():
    """u_i = 84 mm/s, 50 cells: both laws grow a jammed band at constant speed (R^2 >= 0.95) that
    reaches the outer wall; the reduced law's front is faster than the full law's by a measured
    61 % (0.906 against 0.562 m/s; 0.98 against ~0.60 m/s at 800 cells): in the jammed band and
    at the front the reduced law's pressure follows the critical state at once (K -> inf), while
    the full law's builds up at the finite rate K beta gdot_p, which holds its stress lower (the
    0-D case shear1d_reduced_vs_full_law). The bounds pin that difference; they do not claim
    agreement."""
    pb, t_end = annular_shear_jamming(FAST, n_cells=50)
    dae = summarize(solve(pb, t_end, method="dae", n_out=62))
    exp = summarize(solve(pb, t_end, method="explicit", n_out=62))
    assert dae["front_fit_r2"] >= 0.95 and exp["front_fit_r2"] >= 0.95
    assert dae["front_at_wall_rotation_rad"] is not None
    ratio = dae["front_speed_m_per_s"] / exp["front_speed_m_per_s"]
    assert 1.45 < ratio < 1.8, ratio


def test_jacobian_band():
    """The residual's dense finite-difference Jacobian vanishes outside the declared band, at a
    state with a band near jamming and flowing cells (fast case part-way)."""
    pb, t_end = annular_shear_jamming(FAST, n_cells=12)
    res = solve(pb, 0.4 * t_end, method="dae", n_out=4)
    dae = ReducedDAE(pb)
    y = np.zeros(dae.size)
    st = pb.unpack(res.y[-1], res.t[-1])
    y[dae.i_tau] = st["sigma"][:, 3]
    m = pb.material
    y[dae.i_gap] = (m.phi_j - pb.phi0) - (m.phi_j - m.phi_c) * st["f"]
    y[dae.i_gp] = res.field("plastic_shear_rate")[-1]
    y[dae.i_v[dae.i_v >= 0]] = st["v"][dae.i_v >= 0]
    assert y[dae.i_gap].min() < 0.1 * y[dae.i_gap].max()     # a band near jamming, and flow
    yp = np.zeros(dae.size)
    r0, r1 = np.empty(dae.size), np.empty(dae.size)
    dae.residual(res.t[-1], y, yp, r0)
    J = np.zeros((dae.size, dae.size))
    for k in range(dae.size):
        h = 1e-7 * max(abs(y[k]), 1e-6)
        y2 = y.copy()
        y2[k] += h
        dae.residual(res.t[-1], y2, yp, r1)
        J[:, k] = (r1 - r0) / h
    i, k = np.nonzero(J)
    assert np.max(np.abs(i - k)) <= BANDWIDTH
    assert np.max(np.abs(i - k)) == BANDWIDTH           # the band is used, not oversized


def test_resume_matches_uninterrupted(tmp_path):
    """Interrupted at a quarter of the run and resumed: IDA restarts its BDF history, so the
    result agrees to the integration tolerance while the band grows (measured 0.3 % of u_i
    between rtol 1e-4 and 1e-6 there). After the band has reached the wall the locked annulus
    rings elastically (shear waves crossing the gap, damped only by the fluid viscosity) and the
    phase of that ringing is sensitive: rtol 1e-4 and 1e-6 differ by up to 16 % of u_i, so that
    part is not compared."""
    pb, t_end = annular_shear_jamming(FAST, n_cells=20)
    full = solve(pb, t_end, method="dae", n_out=20)
    ck = tmp_path / "ck.npz"

    def hook(t):
        if t > 0.25 * t_end:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt, match="checkpoint"):
        solve(pb, t_end, method="dae", n_out=20, checkpoint=ck, stop_hook=hook)
    res = solve(pb, t_end, method="dae", n_out=20, checkpoint=ck, resume=True)
    assert res.t.size == full.t.size
    grow = full.t <= full.events["front_at_wall"][0]
    assert np.max(np.abs(res.field("v")[grow] - full.field("v")[grow])) / FAST < 5e-3
    assert res.events["front_at_wall"] == pytest.approx(full.events["front_at_wall"], rel=1e-2)


def test_two_phase_refused(tmp_path, capsys):
    pb, t_end = annular_shear_jamming(FAST, n_cells=8, mode="two-phase")
    with pytest.raises(ValueError, match="locked"):
        solve(pb, t_end, method="dae", n_out=2)
    out = tmp_path / "o"
    assert cli_main(["annular", "--method", "dae", "--cells", "8", "--out", str(out)]) == 2
    assert "--mode locked" in capsys.readouterr().err
    assert not out.exists()


def test_creep_transient_matches_full_law():
    """Stress-driven creep (10 Pa on a 1 mm gap, 60 s): no jamming, the pressure stays at the
    critical state, so the reduced law follows the full law's transient as well as its steady
    state (measured: wall speeds within 0.4 % at every output, 4e-5 at the end)."""
    pb = plane_couette(stress=10.0, gap=1e-3, n_cells=16)
    dae = solve(pb, 60.0, method="dae", n_out=20)
    ref = solve(pb, 60.0, method="ida", n_out=20)
    u_dae, u_ref = dae.field("v")[1:, 0], ref.field("v")[1:, 0]
    assert np.max(np.abs(u_dae / u_ref - 1)) < 0.01
    assert abs(u_dae[-1] / u_ref[-1] - 1) < 1e-3
    assert np.max(np.abs(dae.field("f")[-1] - ref.field("f")[-1])) < 1e-3
