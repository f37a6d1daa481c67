"""Front measurement (Han, Peters & Jaeger 2016) on synthetic fields with known fronts."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mpm2d.fronts import (cell_field, fit_speed, front_coefficients, longitudinal_front,
                          transverse_front)

H = 1e-3
NR, NZ = 50, 35
RC = (np.arange(NR) + 0.5) * H
ZC = (np.arange(NZ) + 0.5) * H


def plug(tip, z_front, r_front, v, smooth=2 * H):
    """u_z of a plug: v inside an ellipse-like region below the tip, linear fall over ``smooth``."""
    R, Z = np.meshgrid(RC, ZC, indexing="ij")
    # distance-like coordinate: 0 on the front, positive inside
    inside = np.minimum((Z - z_front) / smooth + 0.5, (r_front - R) / smooth + 0.5)
    inside = np.where(Z > tip, 0.0, inside)
    return v * np.clip(inside, 0.0, 1.0)


@settings(max_examples=50, deadline=None)
@given(z_front=st.floats(5e-3, 25e-3), r_front=st.floats(5e-3, 40e-3))
def test_front_found_to_subcell_accuracy(z_front, r_front):
    tip = 30e-3
    uz = plug(tip, z_front, r_front, -0.2)
    zl = longitudinal_front(uz, RC, ZC, tip, -0.2)
    rt = transverse_front(uz, RC, ZC, tip, 2e-3, -0.2)
    # the half-velocity contour of the linear ramp sits on the front; interpolation between
    # cell centres is exact for a linear ramp sampled by >= 2 cells
    assert abs(zl - z_front) < 1e-9 + 1e-6 and abs(rt - r_front) < 1e-9 + 1e-6


def test_no_front_when_nothing_moves():
    uz = np.zeros((NR, NZ))
    assert np.isnan(longitudinal_front(uz, RC, ZC, 0.02, -0.2))
    assert np.isnan(transverse_front(uz, RC, ZC, 0.02, 2e-3, -0.2))


def test_coefficients_of_steady_fronts():
    v0, k_l, k_t = 0.2, 1.1, 0.55
    t = np.linspace(0, 0.02, 21)
    tip = 0.034 - v0 * t
    zl = tip - 1e-3 - k_l * v0 * t          # relative to the tip, the front runs ahead at k_l v0
    rt = 3e-3 + k_t * v0 * t
    res = front_coefficients(t, zl, rt, v0)
    assert abs(res["k_l"] - k_l) < 1e-9 and abs(res["k_t"] - k_t) < 1e-9
    assert res["r2_longitudinal"] > 0.999999 and abs(res["k_l_over_k_t"] - 2.0) < 1e-9


def test_cell_field_is_the_mass_weighted_mean():
    x = np.array([[0.5e-3, 0.5e-3], [0.6e-3, 0.4e-3], [1.5e-3, 0.5e-3]])
    f = cell_field(x, [1.0, 3.0, 5.0], [1.0, 3.0, 2.0], (0.0, 0.0), H, (3, 2))
    assert f[0, 0] == (1 + 9) / 4 and f[1, 0] == 5.0 and np.isnan(f[2, 1])


def test_fit_speed_r2():
    t = np.linspace(0, 1, 11)
    assert fit_speed(t, 2 * t + 1)["r2"] == 1.0
    noisy = fit_speed(t, 2 * t + 0.5 * np.sin(40 * t))
    assert noisy["r2"] < 0.99 and abs(noisy["speed"] - 2) < 0.5
