"""The parallel builds of the engine's kernels (chosen above kernels.PARALLEL_MIN_POINTS, so the
suite's small scenes never compile them otherwise) give the serial builds' state bit for bit:
a two-phase column (drag, nodal phi gather), the axisymmetric swirl annulus and the impact scene
(contact, hydrostatic term)."""

from __future__ import annotations

import numba as nb
import numpy as np
import pytest

from mpm2d import simulation
from mpm2d.scenes import get_setup

CASES = [("column", {}), ("annular", {}),
         ("impact", dict(radius=0.03, depth=0.03, cells_per_mm=0.5, t_end=0.004))]


def _state(name, params, steps=30):
    sim = get_setup(name)(**params).sim
    for _ in range(steps):
        sim.step()
    out = {}
    for s in sim.sets:
        for k in ("x", "v", "C", "stress", "V"):
            out[f"{s.name}.{k}"] = getattr(s, k).copy()
    return sim, out


@pytest.mark.skipif(nb.config.NUMBA_NUM_THREADS < 2, reason="one thread: no parallel build")
@pytest.mark.parametrize("name, params", CASES, ids=[c[0] for c in CASES])
def test_parallel_builds_match_serial(name, params, monkeypatch):
    serial_sim, serial = _state(name, params)
    assert not serial_sim.par
    monkeypatch.setattr(simulation, "PARALLEL_MIN_POINTS", 0)
    par_sim, par = _state(name, params)
    assert par_sim.par and par_sim.par_grid
    for k in serial:
        assert np.array_equal(serial[k], par[k]), k
