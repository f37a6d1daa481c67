"""Method "dae" of shear1d: the full Table 8 law as a smooth DAE (shear1d.dae).

Physics asserted: on the fast Fig. 3 case the front speed, the time the band reaches the wall and
the velocity, structure and pressure fields agree with the explicit method (the full law stepped
by the local update itself) at every cell count tried, and the front converges with cells; the
regularisation (Table 8's compaction rule with K4 > 0, smoothed switch) is converged: ten times
smaller K4 or width leaves the answer within stated bounds; the Newtonian limit of the slow case
(v = A r + B/r); the steady state of a stress-driven plane Couette cell against rheology's steady
flow curve; a creep transient against the rate-form IDA method; the flow rule holds at a
converted state; the Jacobian's band; resume; refusals. The cost against cell count is a
benchmark (validation/bench_shear1d.py, shear1d_cost_vs_cells), not a timed test.
"""

from __future__ import annotations

import numpy as np
import pytest

import rheology
import shear1d.dae as dae_mod
from shear1d.analytic import annular_steady
from shear1d.cli import main as cli_main
from shear1d.dae import BANDWIDTH, FullLawDAE, solve_x
from shear1d.integrate import solve
from shear1d.scenes import annular_shear_jamming, plane_couette, summarize

SLOW, FAST = 0.84e-3, 84e-3
CELLS = (50, 100, 200)
#: Cell counts at which the explicit method is run too (200 cells of it take a second or more).
COMPARED = (50, 100)


@pytest.fixture(scope="module")
def fast_runs():
    """The fast Fig. 3 case at CELLS with method dae, and at COMPARED with the explicit method
    too (62 outputs, as the benchmark)."""
    runs = {}
    for n in CELLS:
        pb, t_end = annular_shear_jamming(FAST, n_cells=n)
        runs[n] = {m: solve(pb, t_end, method=m, n_out=62)
                   for m in (("dae", "explicit") if n in COMPARED else ("dae",))}
    return runs


def _growth(res):
    """Outputs while the band grows (up to the time it reaches the outer wall)."""
    return res.t <= res.events["front_at_wall"][0]


@pytest.mark.parametrize("n", COMPARED)
def test_fast_front_and_fields_match_explicit(fast_runs, n):
    """Same law, two integrators: front speed within 0.5 % (measured <= 0.07 %), the band
    reaches the outer wall within 0.5 % of the same time, and while it grows the velocity
    profile within 4 % of u_i, f within 0.02 and the pressure within 3 % of its maximum
    (measured at 100 cells: 1.5 % of u_i, 0.005, 0.8 %; what is left is the compaction
    regularisation, test_regularisation_converged, and the explicit method's own step)."""
    d, e = fast_runs[n]["dae"], fast_runs[n]["explicit"]
    sd, se = summarize(d), summarize(e)
    assert sd["front_fit_r2"] >= 0.95 and se["front_fit_r2"] >= 0.95
    assert sd["front_speed_m_per_s"] == pytest.approx(se["front_speed_m_per_s"], rel=5e-3)
    assert d.events["front_at_wall"][0] == pytest.approx(e.events["front_at_wall"][0], rel=5e-3)
    g = _growth(e)
    assert np.max(np.abs(d.field("v")[g] - e.field("v")[g])) < 0.04 * FAST
    assert np.max(np.abs(d.field("f")[g] - e.field("f")[g])) < 0.02
    p_e = e.field("pressure")[g]
    assert np.max(np.abs(d.field("pressure")[g] - p_e)) < 0.03 * p_e.max()
    assert sd["bob_shear_stress_max_Pa"] == pytest.approx(se["bob_shear_stress_max_Pa"],
                                                          rel=0.02)


def test_front_converges_with_cells(fast_runs):
    """The front speed settles as the grid is refined (measured 0.5626, 0.5867, 0.5885 m/s at
    50, 100, 200 cells, the explicit method 0.5622, 0.5867, 0.5887; 0.599-0.600 at 400 and 800
    cells in the benchmark shear1d_cost_vs_cells): the change from 100 to 200 cells is under 1 %
    and under half the change from 50 to 100."""
    s = [summarize(fast_runs[n]["dae"])["front_speed_m_per_s"] for n in CELLS]
    assert abs(s[2] / s[1] - 1) < 0.01, s
    assert abs(s[2] - s[1]) < 0.5 * abs(s[1] - s[0]), s


def test_regularisation_converged(monkeypatch):
    """Ten times smaller K4_REG (compaction closer to instantaneous) or COMPACTION_WIDTH (the
    switch closer to a kink) moves the 50-cell front by under 0.3 % and the velocity profile
    while the band grows by under 2 % of u_i (measured at 100 cells: K4 1 -> 0.1 -> 0.01 brings
    the velocity difference to the explicit method from 2.7 % to 1.5 % to 1.2 % of u_i; the
    smaller K4 needs the tighter rtol)."""
    pb, t_end = annular_shear_jamming(FAST, n_cells=50)
    ref = solve(pb, t_end, method="dae", n_out=62)
    g = _growth(ref)
    for name in ("K4_REG", "COMPACTION_WIDTH"):
        with monkeypatch.context() as mp:
            mp.setattr(dae_mod, name, getattr(dae_mod, name) / 10)
            res = solve(pb, t_end, method="dae", n_out=62, rtol=1e-5)
            assert res.stats["k4" if name == "K4_REG" else "width"] == pytest.approx(
                getattr(dae_mod, name))
        assert summarize(res)["front_speed_m_per_s"] == pytest.approx(
            summarize(ref)["front_speed_m_per_s"], rel=3e-3), name
        assert np.max(np.abs(res.field("v")[g] - ref.field("v")[g])) < 0.02 * FAST, name


def test_newtonian_limit_slow_annular():
    """u_i = 0.84 mm/s: f stays ~0, the profile reaches the steady Newtonian A r + B/r, and the
    rate-form IDA method gives the same answer."""
    pb, t_end = annular_shear_jamming(SLOW, n_cells=30)
    res = solve(pb, t_end, method="dae", n_out=10)
    g = pb.grid
    v = res.field("v")[-1]
    dev = np.max(np.abs(v - annular_steady(g.faces, g.inner, g.outer, SLOW))) / SLOW
    assert dev < 0.005                                   # measured 9.3e-4 (ida: 8.9e-4)
    assert res.field("f").max() < 0.01 * float(rheology.f_jam(pb.phi0, pb.material))
    ref = solve(pb, t_end, method="ida", n_out=10)
    assert np.max(np.abs(ref.field("v")[-1] - v)) / SLOW < 1e-3      # measured 5.6e-5


def test_stress_driven_steady_state_is_the_flow_curve():
    """Plane Couette pushed by the mixture stress of rheology's steady state at taubar = 5 Pa:
    uniform rate, structure and pressure reach the steady flow curve's (Eq. 13 on the critical
    state, where compaction and dilatancy balance: the smoothing does not move it)."""
    m = rheology.get_material("annular_shear")
    st = rheology.steady_state_stress(5.0, m.phi0, m)
    gap = 1e-3
    pb = plane_couette(stress=float(st.shear_stress), gap=gap, n_cells=8)
    res = solve(pb, 100.0, method="dae", n_out=5)
    gdot = res.field("v")[-1][0] / gap
    assert gdot == pytest.approx(float(st.shear_rate), rel=5e-3)     # measured 2.3e-3
    assert res.field("f")[-1] == pytest.approx(float(st.f), rel=5e-3)   # 1.8e-3
    assert res.field("pressure")[-1] == pytest.approx(float(st.pressure), rel=1e-3)  # 3e-5
    assert np.abs(res.field("sigma_rth")[-1]) == pytest.approx(5.0, rel=1e-3)


def test_creep_transient_matches_rate_form():
    """Stress-driven creep (10 Pa on a 1 mm gap, 60 s): the plate's speed follows the rate-form
    IDA method's at every output (measured within 0.54 %, which is the rate form's own error at
    rtol 1e-4: against it at rtol 1e-6 the dae run is within 0.2 %) and the structure ends
    equal (1.4e-5)."""
    pb = plane_couette(stress=10.0, gap=1e-3, n_cells=16)
    dae = solve(pb, 60.0, method="dae", n_out=20)
    ref = solve(pb, 60.0, method="ida", n_out=20)
    u_dae, u_ref = dae.field("v")[1:, 0], ref.field("v")[1:, 0]
    assert np.max(np.abs(u_dae / u_ref - 1)) < 0.01
    assert abs(u_dae[-1] / u_ref[-1] - 1) < 1e-3
    assert np.max(np.abs(dae.field("f")[-1] - ref.field("f")[-1])) < 1e-3


def _dae_state(dae, pb, res, k):
    """The DAE unknowns of output k of a dae run (x from the flow rule, taubar = Y(x) p)."""
    st = pb.unpack(res.y[k], res.t[k])
    S, p = st["sigma"], res.field("pressure")[k]
    m = pb.material
    y = np.zeros(dae.size)
    y[dae.i_c] = S[:, 0] + p
    y[dae.i_c + 1] = S[:, 1] + p
    y[dae.i_c + 2] = S[:, 3]
    y[dae.i_p] = p
    y[dae.i_gap] = (m.phi_j - pb.phi0) - (m.phi_j - m.phi_c) * st["f"]
    szz = S[:, 2] + p
    tb = np.sqrt(0.5 * ((S[:, 0] + p) ** 2 + (S[:, 1] + p) ** 2 + szz ** 2) + S[:, 3] ** 2)
    y[dae.i_x] = [solve_x(t, pp, gp, dae.P, 0.01) for t, pp, gp in zip(tb, p, y[dae.i_gap])]
    y[dae.i_v[dae.i_v >= 0]] = st["v"][dae.i_v >= 0]
    return y


def test_flow_rule_and_jacobian_band():
    """At a state part-way through the fast case (a band near jamming, flowing cells): the plastic
    rate recovered from the flow rule is the one the run reported, and the residual's dense
    finite-difference Jacobian vanishes outside the declared band, which it uses."""
    pb, t_end = annular_shear_jamming(FAST, n_cells=12)
    res = solve(pb, 0.5 * t_end, method="dae", n_out=4)
    dae = FullLawDAE(pb)
    y = _dae_state(dae, pb, res, -1)
    assert y[dae.i_gap].min() < 0.1 * y[dae.i_gap].max()     # a band near jamming, and flow
    gp = np.array([dae_mod.plastic_rate(x, p, dae.P) for x, p in zip(y[dae.i_x], y[dae.i_p])])
    reported = res.field("plastic_shear_rate")[-1]
    assert np.allclose(gp, reported, rtol=1e-3, atol=1e-3 * np.abs(reported).max())
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
    assert np.max(np.abs(i - k)) == BANDWIDTH          # inside the band, and the band is used


def test_resume_matches_uninterrupted(tmp_path):
    """Interrupted at a quarter of the run and resumed: IDA restarts its BDF history, so the
    result agrees to the integration tolerance while the band grows. After the band has
    reached the wall the locked annulus rings elastically (shear waves crossing the gap, damped
    only by the fluid viscosity) and the phase of that ringing is sensitive, so that part is not
    compared."""
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


def test_refusals(tmp_path, capsys):
    """Two-phase mode, and a phi where the yield ratio at rest mu_1 + K3 (phi - phi_j) is not
    positive, are refused: one line, exit 2, nothing written."""
    pb, t_end = annular_shear_jamming(FAST, n_cells=8, mode="two-phase")
    with pytest.raises(ValueError, match="locked"):
        solve(pb, t_end, method="dae", n_out=2)
    out = tmp_path / "o"
    assert cli_main(["annular", "--method", "dae", "--mode", "both", "--cells", "8", "--out",
                     str(out)]) == 2
    assert "--mode locked" in capsys.readouterr().err
    assert not out.exists()
    assert cli_main(["couette", "--speed", "0.01", "--method", "dae", "--phi", "0.2", "--out",
                     str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "mu_1 + K3 (phi0 - phi_j) > 0" in err
    assert not out.exists()
    pb = plane_couette(speed=0.01, gap=1e-3, n_cells=8, phi0=0.2)
    with pytest.raises(ValueError, match="phi0 must exceed"):
        solve(pb, 0.01, method="dae", n_out=2)
