"""The Table 8 local update: consistency, bounds, dissipation, objectivity, steady simple shear."""

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import rheology as r
from rheology.local_update import (COMPACTION, ELASTIC, NOUT, SEPARATED, SHEAR_FLOW,
                                   kernel_parameters, update_points_serial)
from rheology_strategies import materials

SET = settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def random_states(m, seed, n=400):
    """Random symmetric stresses, velocity gradients, phi (a third within 1e-12..1e-3 of phi_m), f."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, 3, 3))
    scale = 10.0 ** rng.uniform(-3, 5, n)[:, None, None] * m.tau_star
    sig = 0.3 * (A + A.transpose(0, 2, 1)) * scale - np.eye(3) * scale * rng.uniform(-0.2, 2, n)[:, None, None]
    L = rng.normal(size=(n, 3, 3)) * 10.0 ** rng.uniform(-3, 3, n)[:, None, None]
    f = rng.uniform(0, 1, n)
    phi = rng.uniform(0.3, 0.98, n) * m.phi_j
    k = n // 3
    phi[:k] = np.clip(r.phi_m(f[:k], m) * (1 + rng.choice([-1, 1], k) * 10.0 ** rng.uniform(-12, -3, k)), 0, 0.99)
    dt = 10.0 ** rng.uniform(-7, -1)
    return sig, L, phi, f, dt


@SET
@given(materials(), st.integers(0, 2 ** 32 - 1))
def test_yield_conditions_bounds_and_dissipation(m, seed):
    sig, L, phi, f, dt = random_states(m, seed)
    u = r.local_update(sig, L, phi, f, dt, m)
    taubar, p = r.invariants(u.stress)
    scale = np.abs(r.invariants(sig)[0]) + np.abs(r.invariants(sig)[1]) + m.G * dt * np.abs(L).max(axis=(1, 2)) + 1e-300
    f1, f2, f3 = r.yield_functions(u.stress, u.shear_rate_p, phi, f, m, u.xi2)
    flowing = (u.case == SHEAR_FLOW) | (u.case == COMPACTION)
    assert np.all(np.abs(f1[flowing]) <= 1e-9 * scale[flowing])          # on the yield surface
    assert np.all(f1[u.case == ELASTIC] <= 1e-9 * scale[u.case == ELASTIC])
    assert np.all(np.abs(f3[u.case == COMPACTION]) <= 1e-9 * scale[u.case == COMPACTION])
    assert np.all(u.xi2 <= 0) and np.all(u.xi1 >= 0) and np.all(u.shear_rate_p >= 0)
    assert np.all(p >= -1e-12 * scale) and np.all(taubar[u.case == SEPARATED] == 0)
    np.testing.assert_allclose(taubar, u.taubar, rtol=1e-9, atol=1e-12 * scale.max())
    # plastic power sigma : D^p = gdot mu_p p - p xi2 >= 0
    diss = r.plastic_dissipation(u.stress, u.shear_rate_p, u.beta, u.xi1, u.xi2)
    assert np.all(diss >= -1e-9 * scale * (u.shear_rate_p + np.abs(u.xi2) + 1e-300))
    # structure stays in [0, max(f_n, f_m)]
    assert np.all(u.f >= 0) and np.all(u.f <= np.maximum(f, r.f_max(phi, m)) + 1e-14)


def _rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


@SET
@given(materials(), st.integers(0, 2 ** 32 - 1))
def test_frame_indifference(m, seed):
    """Rotating stress and velocity gradient rotates the updated stress; scalars are unchanged."""
    sig, L, phi, f, dt = random_states(m, seed, n=200)
    Q = _rotation(np.random.default_rng(seed + 1))
    a = r.local_update(sig, L, phi, f, dt, m)
    rot = lambda T: Q @ T @ Q.T
    b = r.local_update(rot(sig), rot(L), phi, f, dt, m)
    scale = np.abs(sig).max() + m.G * dt * np.abs(L).max() + 1e-300
    np.testing.assert_allclose(b.stress, rot(a.stress), atol=1e-8 * scale)
    np.testing.assert_array_equal(a.case, b.case)
    # Rotating the inputs perturbs them by roundoff of `scale`; the return to a small taubar from a
    # large trial stress (G dt gdot_p >> taubar) cancels, so stress-like outputs are compared to
    # roundoff of `scale`, and f (which follows taubar) to 1e-6.
    for k in ("taubar", "pressure"):
        np.testing.assert_allclose(getattr(b, k), getattr(a, k), rtol=1e-7, atol=1e-13 * scale)
    for k in ("f", "shear_rate_p"):
        np.testing.assert_allclose(getattr(b, k), getattr(a, k), rtol=1e-6,
                                   atol=1e-12 * np.abs(getattr(a, k)).max() + 1e-300)


def drive_simple_shear(m, phi, gdot, nstep, strain_per_step, p0, until_steady=False):
    """Homogeneous isochoric simple shear v_x = gdot y through the local update kernel.

    With ``until_steady`` the drive goes on in chunks of ``nstep`` steps (up to 40) until sigma_xy
    changes by less than 1e-11 relative over a chunk; returns (stress, out, converged).
    """
    P = kernel_parameters(m)
    sig = -p0 * np.eye(3)[None].copy()
    L = np.zeros((1, 3, 3))
    L[0, 0, 1] = gdot
    ph, f = np.array([phi]), np.array([0.0])
    so, out = np.empty_like(sig), np.empty((1, NOUT))
    dt = strain_per_step / gdot
    for _ in range(40 if until_steady else 1):
        before = sig[0, 0, 1]
        for _ in range(nstep):
            update_points_serial(sig, L, ph, f, dt, P, so, out)
            sig, f = so.copy(), out[:, 0].copy()
        converged = abs(sig[0, 0, 1] - before) <= 1e-11 * abs(sig[0, 0, 1])
        if converged or not until_steady:
            break
    return (sig[0], out[0], converged) if until_steady else (sig[0], out[0])


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(materials(buckling="always"), st.floats(0.3, 0.9), st.floats(-1.5, 1.5))
def test_steady_simple_shear_recovers_eq1_and_eq2(m, s, logtau):
    """The update driven to steady simple shear gives taubar = eta0 eta_g gdot (Eq. 1), p (Eq. 2), Eq. 13."""
    assume(m.K0 >= 0.1)
    phi = s * m.phi_c
    target = r.steady_state_stress(10.0 ** logtau * m.tau_star, phi, m)
    gdot = float(target.shear_rate)
    branches = r.steady_states_rate(gdot, phi, m)
    assume(branches.f.size == 1)                         # a unique (stable) rate-controlled state
    assume(float(target.taubar) < 1e-3 * m.G)            # elastically stiff, as in the paper
    # near the fold of an S-shaped curve the structure relaxes slowly (critical slowing down):
    # drive until steady rather than for a fixed strain
    nstep = int(10 / (m.K0 * 0.05))
    sig, out, converged = drive_simple_shear(m, phi, gdot, nstep, 0.05, float(target.pressure),
                                             until_steady=True)
    assume(converged)
    taubar, p = r.invariants(sig)
    np.testing.assert_allclose(sig[0, 1], target.taubar, rtol=2e-5)       # Eq. (1), granular part
    np.testing.assert_allclose(p, target.pressure, rtol=2e-5)             # Eq. (2)
    np.testing.assert_allclose(out[0], target.f, rtol=2e-5)               # Eq. (13)
    np.testing.assert_allclose(out[1], gdot, rtol=2e-5)                   # all of it plastic


def test_hermes_steady_shear_three_rates_tight():
    m = r.get_material("hermes2016", G=1e6, K=2e6, K0=1.0)
    for gdot in (0.01, 0.1, 1.0):
        target = r.steady_states_rate(gdot, 0.48, m)
        sig, out = drive_simple_shear(m, 0.48, gdot, 20000, 0.005, p0=1e-3)
        np.testing.assert_allclose([sig[0, 1], r.invariants(sig)[1], out[0]],
                                   [target.taubar[0], target.pressure[0], target.f[0]], rtol=1e-8)


def test_elastic_jammed_solid_is_linear_elastic():
    m = r.get_material("annular_shear")
    sig0 = -1e3 * np.eye(3)
    L = np.diag([-1.0, 0.0, 0.0]) * 1e-3                 # small uniaxial compression
    dt = 1e-2
    u = r.local_update(sig0, L, 0.54, 0.5, dt, m)        # phi > phi_m(0.5): jammed
    assert u.case == ELASTIC and u.shear_rate_p == 0
    D = L * dt
    expect = sig0 + 2 * m.G * (D - np.trace(D) / 3 * np.eye(3)) + m.K * np.trace(D) * np.eye(3)
    np.testing.assert_allclose(u.stress, expect, rtol=1e-14)


def test_loose_skeleton_at_rest_carries_no_pressure_and_separates_in_tension():
    m = r.get_material("annular_shear")
    u = r.local_update(-50.0 * np.eye(3), np.zeros((3, 3)), 0.45, 0.0, 1e-4, m)   # phi < phi_m
    assert u.case == COMPACTION and np.allclose(u.stress, 0) and u.xi2 < 0
    u = r.local_update(np.zeros((3, 3)), 0.1 * np.eye(3), 0.55, 0.0, 1e-4, m)     # expansion
    assert u.case == SEPARATED and np.allclose(u.stress, 0) and u.xi1 > 0


def test_near_jamming_is_robust():
    m = r.get_material("intruder")
    n = 2000
    rng = np.random.default_rng(3)
    f = rng.uniform(0, 1, n)
    phi = r.phi_m(f, m) + rng.choice([-1, 1], n) * 10.0 ** rng.uniform(-15, -6, n)
    L = np.zeros((n, 3, 3))
    L[:, 0, 1] = 10.0 ** rng.uniform(-2, 3, n)
    sig = -np.eye(3) * 10.0 ** rng.uniform(0, 4, n)[:, None, None]
    u = r.local_update(sig, L, phi, f, 1e-6, m)
    assert np.all(np.isfinite(u.stress)) and np.all(np.isfinite(u.shear_rate_p))


@pytest.mark.parametrize("kw, name", [
    (dict(stress=np.zeros((3, 2))), "shape"), (dict(stress=np.full((3, 3), np.nan)), "stress"),
    (dict(stress=np.array([[0, 1, 0], [0, 0, 0], [0, 0, 0.0]])), "symmetric"),
    (dict(velocity_gradient=np.full((3, 3), np.inf)), "velocity_gradient"),
    (dict(phi=1.0), "phi"), (dict(phi=-0.1), "phi"), (dict(f=1.5), "f"), (dict(dt=0.0), "dt"),
    (dict(dt=float("nan")), "dt"),
])
def test_bad_input(kw, name):
    args = dict(stress=-np.eye(3), velocity_gradient=np.zeros((3, 3)), phi=0.5, f=0.1, dt=1e-4,
                m=r.get_material("annular_shear"))
    args.update(kw)
    with pytest.raises(ValueError, match=name):
        r.local_update(**args)


def test_missing_moduli_are_named():
    with pytest.raises(ValueError, match="G .* is not set for material hermes2016"):
        r.local_update(-np.eye(3), np.zeros((3, 3)), 0.5, 0.1, 1e-4, r.get_material("hermes2016"))


@SET
@given(materials(), st.integers(0, 2 ** 32 - 1))
def test_dilatancy_from_a_vanishing_trial_pressure(m, seed):
    """Expansion leaves a trial pressure 1e-15..1e-2 of p_n: all of the final pressure is made by
    dilatancy, where gdot(beta) is too steep to resolve; the update must still land on f_1 = 0."""
    rng = np.random.default_rng(seed)
    n = 200
    p_n = 10.0 ** rng.uniform(-2, 3, n) * m.tau_star
    sig = -p_n[:, None, None] * np.eye(3)
    sig[:, 0, 1] = sig[:, 1, 0] = rng.uniform(0.1, 1.0, n) * p_n
    dt = 10.0 ** rng.uniform(-5, -1)
    frac = 10.0 ** rng.uniform(-15, -2, n)
    L = np.zeros((n, 3, 3))
    L[:, 0, 1] = 10.0 ** rng.uniform(-2, 2, n)
    L[:, 1, 1] = p_n * (1 - frac) / (m.K * dt)        # p* = p_n - K dt tr(D) = frac p_n (+ spin)
    f = rng.uniform(0, 0.5, n)
    phi = rng.uniform(0.5, 0.99, n) * r.phi_m(f, m)
    u = r.local_update(sig, L, phi, f, dt, m)
    f1, _, _ = r.yield_functions(u.stress, u.shear_rate_p, phi, f, m, u.xi2)
    flowing = u.case == SHEAR_FLOW
    # tolerance: relative to the final stress, above the roundoff of tau* - G dt gdot
    trial = np.array([r.invariants(sig[k] + dt * 2 * m.G * 0.5 * (L[k] + L[k].T))[0] for k in range(n)])
    scale = 1e-9 * (u.taubar + m.mu_c * u.pressure) + 2e-14 * trial
    assert np.all(np.abs(f1[flowing]) <= scale[flowing])


def test_elastic_trial_is_the_jaumann_predictor():
    """The unrolled kernel equals sigma + dt [2G D' + K tr(D) 1 + W sigma - sigma W] term by term."""
    from rheology.local_update import elastic_trial
    rng = np.random.default_rng(11)
    G, K, dt = 2.0, 3.0, 0.1
    for _ in range(200):
        sig, L = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
        D, W = 0.5 * (L + L.T), 0.5 * (L - L.T)
        expect = sig + dt * (2 * G * (D - np.trace(D) / 3 * np.eye(3)) + K * np.trace(D) * np.eye(3)
                             + W @ sig - sig @ W)
        out = np.empty((3, 3))
        elastic_trial(sig, L, dt, G, K, out)
        np.testing.assert_allclose(out, expect, rtol=1e-13, atol=1e-14)



def test_plane_jaumann_is_the_full_predictor_without_out_of_plane_shear():
    """jaumann_elastic_plane (mpm2d's elastic update in plane strain and axisymmetry without swirl)
    equals the full predictor on a symmetric stress and a gradient with no out-of-plane shear, and
    the full predictor keeps those components exactly zero."""
    from rheology.local_update import jaumann_elastic, jaumann_elastic_plane
    rng = np.random.default_rng(12)
    for _ in range(200):
        G, K, dt = 10.0 ** rng.uniform(3, 8), 10.0 ** rng.uniform(3, 8), 10.0 ** rng.uniform(-7, -3)
        s00, s01, s11, s22 = rng.normal(size=4) * 10.0 ** rng.uniform(0, 5)
        l00, l01, l10, l11, l22 = rng.normal(size=5) * 10.0 ** rng.uniform(-2, 3)
        full = jaumann_elastic((s00, s01, 0.0, s01, s11, 0.0, 0.0, 0.0, s22),
                               (l00, l01, 0.0, l10, l11, 0.0, 0.0, 0.0, l22), dt, G, K)
        assert full[2] == full[5] == full[6] == full[7] == 0.0
        plane = jaumann_elastic_plane(s00, s01, s11, s22, l00, l01, l10, l11, l22, dt, G, K)
        scale = abs(s00) + abs(s01) + abs(s11) + abs(s22) + dt * (G + K) * (
            abs(l00) + abs(l01) + abs(l10) + abs(l11) + abs(l22))
        np.testing.assert_allclose(plane, (full[0], full[1], full[4], full[8]), rtol=0,
                                   atol=1e-14 * scale)
        assert abs(full[3] - full[1]) <= 1e-14 * scale       # symmetric to roundoff

# ------------------------------------------------------------------ zero points, warm start, Newton
def test_zero_points_give_empty_results():
    m = r.get_material("annular_shear")
    u = r.local_update(np.zeros((0, 3, 3)), np.zeros((0, 3, 3)), np.zeros(0), np.zeros(0), 1e-4, m,
                       plastic_rate=np.zeros(0))
    assert u.stress.shape == (0, 3, 3) and u.f.shape == (0,) and u.case.shape == (0,)
    u = r.local_update(np.zeros((2, 0, 3, 3)), np.zeros((3, 3)), 0.5, 0.1, 1e-4, m)
    assert u.stress.shape == (2, 0, 3, 3) and u.taubar.shape == (2, 0) and u.evaluations.size == 0


def test_plastic_rate_must_be_a_writable_array_of_the_points_shape():
    m = r.get_material("annular_shear")
    args = (-np.eye(3)[None].repeat(3, 0), np.zeros((3, 3, 3)), 0.5, 0.1, 1e-4, m)
    for bad in (np.zeros(2), [0.0, 0.0, 0.0], np.zeros(3, dtype=np.float32), np.full(3, np.inf)):
        with pytest.raises(ValueError, match="plastic_rate"):
            r.local_update(*args, plastic_rate=bad)


def _sheared_batch(m, n, seed):
    """Points in steady dilatant shear flow at random rates, then sheared 2% faster (MPM-like)."""
    rng = np.random.default_rng(seed)
    phi = rng.uniform(0.40, 0.50, n)
    st = r.steady_state_stress(10.0 ** rng.uniform(-2, 3, n), phi, m)
    sig = np.zeros((n, 3, 3))
    sig[:, 0, 1] = sig[:, 1, 0] = st.taubar
    sig -= st.pressure[:, None, None] * np.eye(3)
    L = np.zeros((n, 3, 3))
    L[:, 0, 1] = st.shear_rate * 1.02
    L[:, 1, 1] = rng.normal(0, 1e-3, n) * st.shear_rate          # a little expansion/compression
    return sig, L, phi, np.asarray(st.f, float), np.asarray(st.shear_rate, float)


def test_warm_start_and_newton_agree_with_the_bracket_in_fewer_evaluations():
    """Twenty steps of a sheared batch: the Newton solve (cold, and warm from the previous rate)
    gives the bracket-only (Brent) answer to the solver's tolerance, in fewer residual evaluations,
    and every flowing point sits on the yield surface f_1 = 0."""
    m = r.get_material("annular_shear")
    P = kernel_parameters(m)
    sig, L, phi, f, g = _sheared_batch(m, 300, 5)
    dt = 2e-3 / np.median(L[:, 0, 1])
    states = {k: (sig.copy(), f.copy()) for k in ("bracket", "cold", "warm")}
    g_warm = g.copy()
    evals = {k: [] for k in states}
    for _ in range(20):
        res = {}
        for k, (s, ff) in states.items():
            so, o = np.empty_like(s), np.empty((len(phi), NOUT))
            kw = dict(newton=False) if k == "bracket" else dict(g_prev=g_warm) if k == "warm" else {}
            update_points_serial(s, L, phi, ff, dt, P, so, o, **kw)
            res[k] = (so, o)
            flow = o[:, 12] == SHEAR_FLOW
            evals[k].append(o[flow, 13])
            f1 = r.yield_functions(so, o[:, 1], phi, ff, m, o[:, 3])[0]
            scale = np.abs(s).max(axis=(1, 2))
            assert np.all(np.abs(f1[flow]) <= 1e-9 * scale[flow])
        ref_s, ref_o = res["bracket"]
        for k in ("cold", "warm"):
            so, o = res[k]
            np.testing.assert_array_equal(o[:, 12], ref_o[:, 12])
            np.testing.assert_allclose(so, ref_s, rtol=0, atol=1e-9 * np.abs(ref_s).max())
            np.testing.assert_allclose(o[:, 1], ref_o[:, 1], rtol=1e-9)
        g_warm = res["warm"][1][:, 1].copy()
        states = {k: (res[k][0], res[k][1][:, 0].copy()) for k in states}
    mean = {k: np.concatenate(v).mean() for k, v in evals.items()}
    assert mean["cold"] <= 0.5 * mean["bracket"] and mean["warm"] <= 0.5 * mean["bracket"], mean


@SET
@given(materials(), st.integers(0, 2 ** 32 - 1), st.sampled_from([0.0, -1.0, np.nan, 1e-300, 1e-12,
                                                               1e-3, 1.0, 1e3, 1e12, 1e300]))
def test_any_warm_start_gives_the_cold_answer(m, seed, g_prev):
    """A wrong warm start (zero, tiny, huge, NaN) only moves the start of the safeguarded Newton:
    the result equals the cold start's to the solver tolerance on random states of every case."""
    sig, L, phi, f, dt = random_states(m, seed, n=200)
    a = r.local_update(sig, L, phi, f, dt, m)
    g = np.full(len(phi), g_prev)
    b = r.local_update(sig, L, phi, f, dt, m, plastic_rate=g)
    np.testing.assert_array_equal(a.case, b.case)
    np.testing.assert_array_equal(g, b.shear_rate_p)                 # written back
    scale = np.abs(sig).max(axis=(1, 2)) + m.G * dt * np.abs(L).max(axis=(1, 2)) + 1e-300
    assert np.all(np.abs(b.stress - a.stress).max(axis=(1, 2)) <= 1e-8 * scale)
    f1 = r.yield_functions(b.stress, b.shear_rate_p, phi, f, m, b.xi2)[0]
    flowing = b.case == SHEAR_FLOW
    assert np.all(np.abs(f1[flowing]) <= 1e-9 * scale[flowing])



@SET
@given(materials(), st.integers(0, 2 ** 32 - 1))
def test_block_update_equals_the_point_update(m, seed):
    """update_block (the vectorised stages: trial, critical-state estimates, Newton on
    (beta, gdot_p) for the whole block, the residual test) gives update_point's answer point by
    point to the solver tolerance, case for case, on random states of every case."""
    from rheology.local_update import BLOCK, NWORK, update_block, update_point
    sig, L, phi, f, dt = random_states(m, seed, n=BLOCK)
    m.require("G", "K", "K0")
    P = kernel_parameters(m)
    so, o = np.empty_like(sig), np.empty((BLOCK, NOUT))
    W = np.empty((NWORK, BLOCK))
    update_block(sig, L, phi, f, np.full(BLOCK, -1.0), dt, P, so, o, W, np.empty((3, 3)),
                 np.empty((3, 3)), np.empty((3, 3)), np.empty(NOUT))
    for k in range(BLOCK):
        s1, o1 = np.empty((3, 3)), np.empty(NOUT)
        update_point(sig[k], L[k], phi[k], f[k], dt, P, s1, o1)
        assert o[k, 12] == o1[12], (k, o[k], o1)
        scale = np.abs(sig[k]).max() + m.G * dt * np.abs(L[k]).max() + 1e-300
        assert np.abs(so[k] - s1).max() <= 1e-8 * scale, k
        assert o[k, 0] == pytest.approx(o1[0], rel=1e-8, abs=1e-12)
        assert o[k, 1] == pytest.approx(o1[1], rel=1e-8, abs=1e-300)


def test_block_update_finishes_a_sheared_batch_itself():
    """On sheared batches the block's own path (not the point-by-point fallback) finishes the
    flowing points below jamming that update_point solves at its first residual test (>= 95%: the
    test asks for |R| at the roundoff floor, which an iterate one ulp away can miss; the others,
    whose residual reaches the floor only after 4-10 evaluations, go through update_point too):
    the speed of mpm2d's suspensions rests on it."""
    from rheology.local_update import BLOCK, NWORK, update_block, update_point
    m = r.get_material("annular_shear")
    P = kernel_parameters(m)
    easy = finished = 0
    for seed in range(4):
        sig, L, phi, f, g = _sheared_batch(m, BLOCK, seed)
        dt = 2e-3 / np.median(L[:, 0, 1])
        so, o = np.empty_like(sig), np.empty((BLOCK, NOUT))
        W = np.empty((NWORK, BLOCK))
        update_block(sig, L, phi, f, g, dt, P, so, o, W, np.empty((3, 3)), np.empty((3, 3)),
                     np.empty((3, 3)), np.empty(NOUT))
        below = (o[:, 12] == SHEAR_FLOW) & (phi < r.phi_m(f, m))
        for k in np.flatnonzero(below):
            s1, o1 = np.empty((3, 3)), np.empty(NOUT)
            update_point(sig[k], L[k], phi[k], f[k], dt, P, s1, o1, g[k])
            if o1[13] == 1:
                easy += 1
                finished += W[15, k] == 2.0
    assert easy >= BLOCK // 2 and finished >= 0.95 * easy, (finished, easy)

def test_jammed_yielding_points_solve_in_one_evaluation_and_agree_with_the_bracket():
    """Points just above phi_m sheared for ten steps (dilatancy builds the pressure): the Newton
    solve, cold and warm, lands where the bracket does, in a fraction of its evaluations."""
    m = r.get_material("annular_shear")
    P = kernel_parameters(m)
    rng = np.random.default_rng(3)
    n = 300
    f = rng.uniform(0, 0.3, n)
    phi = r.phi_m(f, m) + rng.uniform(1e-4, 2e-3, n)
    p0 = rng.uniform(10, 1000, n)
    sig = -p0[:, None, None] * np.eye(3)
    sig[:, 0, 1] = sig[:, 1, 0] = 0.3 * p0
    L = np.zeros((n, 3, 3))
    L[:, 0, 1] = rng.uniform(1, 100, n)
    states = {k: (sig.copy(), f.copy(), np.full(n, -1.0)) for k in ("bracket", "cold", "warm")}
    evals = {k: [] for k in states}
    for _ in range(10):
        res = {}
        for k, (s, ff, g) in states.items():
            so, o = np.empty_like(s), np.empty((n, NOUT))
            kw = dict(newton=False) if k == "bracket" else dict(g_prev=g) if k == "warm" else {}
            update_points_serial(s, L, phi, ff, 1e-5, P, so, o, **kw)
            res[k] = (so, o)
            evals[k].append(o[o[:, 12] == SHEAR_FLOW, 13])
        for k in ("cold", "warm"):
            np.testing.assert_array_equal(res[k][1][:, 12], res["bracket"][1][:, 12])
            np.testing.assert_allclose(res[k][0], res["bracket"][0], rtol=0,
                                       atol=1e-9 * np.abs(res["bracket"][0]).max())
        states = {k: (res[k][0], res[k][1][:, 0].copy(), res[k][1][:, 1].copy()) for k in states}
    mean = {k: np.concatenate(v).mean() for k, v in evals.items()}
    assert np.concatenate(evals["cold"]).size > n                       # most points yield
    assert mean["cold"] <= 0.25 * mean["bracket"] and mean["warm"] <= 0.25 * mean["bracket"], mean


def test_material_by_name_equals_material_object():
    """local_update takes the material as a name or a Material, like every public function."""
    sig = -np.eye(3) * 50.0
    L = np.zeros((3, 3))
    L[0, 1] = 2.0
    by_name = r.local_update(sig, L, 0.5, 0.1, 1e-3, "annular_shear")
    by_obj = r.local_update(sig, L, 0.5, 0.1, 1e-3, r.get_material("annular_shear"))
    assert np.array_equal(by_name.stress, by_obj.stress) and by_name.f == by_obj.f
