"""runkit.ida: IDA with named events (root times against the exact solution), a DAE with an
algebraic unknown, and a failure whose SUNDIALS text is captured into its one line."""

from __future__ import annotations

import math
import types

import numpy as np
import pytest

from runkit.ida import IDAFailed, Solver, captured

K = 2.0                                           # decay rate [1/s]


def decay(t, y, yp, res):
    res[0] = yp[0] + K * y[0]


def test_an_event_fires_at_the_exact_time_and_the_solution_is_exact():
    """y' = -K y, y(0) = 1: the root of y - 1/2 is at ln 2 / K; y = exp(-K t) to the tolerance."""
    s = Solver(decay, rtol=1e-10, atol=1e-14, names=("half",), direction=(-1,), stop=(True,),
               events=lambda t, y, yp, out: out.__setitem__(0, y[0] - 0.5))
    times = np.linspace(0.0, 2.0, 21)
    sol, roots = s.solve(times, [1.0], [-K])
    assert [name for _, name, _ in roots] == ["half"] and roots[0][2] == -1
    assert roots[0][0] == pytest.approx(math.log(2.0) / K, rel=1e-8)
    assert sol.t[-1] == pytest.approx(roots[0][0], rel=1e-12)          # it stopped there
    np.testing.assert_allclose(sol.y[:, 0], np.exp(-K * sol.t), rtol=1e-7)


def test_advance_records_roots_and_goes_on_past_those_that_do_not_stop():
    """y'' = -y (x = sin t): the zero crossings of x are at k pi; a rising one at 2 pi stops."""
    def osc(t, y, yp, res):
        res[0] = yp[0] - y[1]
        res[1] = yp[1] + y[0]

    s = Solver(osc, rtol=1e-10, atol=1e-12, names=("down", "up"), direction=(-1, 1),
               events=lambda t, y, yp, out: out.__setitem__(slice(None), [y[0], y[0]]))
    s.start(0.0, [0.0, 1.0], [1.0, 0.0])
    sol, roots = s.advance(5.0)                              # passes pi (falling)
    assert [n for _, n, _ in roots] == ["down"] and float(sol.t) == pytest.approx(5.0)
    assert roots[0][0] == pytest.approx(math.pi, rel=1e-8)
    sol, roots = s.advance(10.0, stop_on=("up",))            # stops at 2 pi (rising)
    assert [n for _, n, _ in roots] == ["up"]
    assert float(sol.t) == pytest.approx(2 * math.pi, rel=1e-8)
    assert float(np.ravel(sol.y)[1]) == pytest.approx(1.0, rel=1e-6)   # x' = cos(2 pi)


def test_a_dae_with_an_algebraic_unknown():
    """x' = -z, 0 = z - K x: x = exp(-K t), z = K x."""
    def res(t, y, yp, r):
        r[0] = yp[0] + y[1]
        r[1] = y[1] - K * y[0]

    s = Solver(res, rtol=1e-10, atol=1e-14, algebraic_idx=[1], band=1)
    sol, _ = s.solve(np.linspace(0, 1, 11), [1.0, K], [-K, -K * K])
    np.testing.assert_allclose(sol.y[:, 0], np.exp(-K * sol.t), rtol=1e-7)
    np.testing.assert_allclose(sol.y[:, 1], K * sol.y[:, 0], rtol=1e-9)   # Newton tolerance


def test_a_failure_is_one_line_with_what_sundials_printed_and_nothing_on_stdout(capfd):
    s = Solver(lambda t, y, yp, r: r.__setitem__(0, yp[0] + 1e6 * y[0] ** 3), rtol=1e-8,
               atol=1e-30, max_num_steps=5, describe=lambda t, y: f"y = {y[0]:.3g}")
    with pytest.raises(IDAFailed) as e:
        s.solve([0.0, 1.0, 2.0], [1.0], [-1e6])
    msg = str(e.value)
    assert msg.startswith("IDA failed at t = ") and "(target 2 s)" in msg
    assert "(status -1); y = " in msg and "[SUNDIALS: IDASolve, Error: -22]" in msg
    assert "\n" not in msg and e.value.sol.t.size >= 1          # the outputs reached are kept
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_a_failed_step_reports_a_time_it_reached():
    """A step that fails may leave its t unset (shear1d printed "IDA failed at t = 6.9e-310 s"):
    the failure names the last time reached, between the start and the target."""
    s = Solver(lambda t, y, yp, r: r.__setitem__(0, yp[0] + 1e6 * y[0] ** 3), rtol=1e-8,
               atol=1e-30, max_num_steps=5)
    s.start(0.5, [1.0], [-1e6])
    with pytest.raises(IDAFailed) as e:
        s.advance(2.0)
    assert 0.5 <= e.value.t <= 2.0 and s.t_reached >= 0.5
    assert f"IDA failed at t = {e.value.t:.6g} s (target 2 s)" in str(e.value)
    unset = types.SimpleNamespace(t=np.array([6.9e-310]), message="invalid input", status=-22)
    assert IDAFailed(unset, 2.0, t_reached=0.75).t == 0.75
    assert str(IDAFailed(unset, 2.0, t_reached=0.75)).startswith("IDA failed at t = 0.75 s")


def test_captured_takes_python_and_c_level_output(capfd):
    import ctypes

    with captured() as c:
        print("python line")
        ctypes.CDLL(None).printf(b"c line\n")
    assert c.text == "python line c line"
    assert capfd.readouterr().out == ""
