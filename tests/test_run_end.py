"""Runs that end early keep their rows up to the end (rheology.run_end): rheometer transients
at the elastic-strain limit or a solver failure, shear1d and mpm2d runs likewise.

Each test checks the physics of the rows kept (the limit reached and never passed, the rows the
unlimited run computes at the same times, the imposed ramp), the end record, the console line,
the exit status 3 and the mark on the figure."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from runkit.plotting import plt

from rheology.elastic import ELASTIC_STRAIN_LIMIT
from rheology.run_end import ENDED_EARLY, EndedEarly, RunEnd, mark_end, run_record

G = 1.0e4                     # the transients' default modulus (hermes2016 has none)
TAU_LIMIT = ELASTIC_STRAIN_LIMIT * G


@pytest.fixture
def figures(monkeypatch):
    """The figures the commands save (runkit.io.atomic_savefig, wherever it is imported), by
    file name: per axes its lines' (x, y) data and its texts."""
    import sys

    import mpm2d.cli  # noqa: F401  (every command's modules, imported)
    import rheometer.cli  # noqa: F401
    import runkit.io
    import shear1d.cli  # noqa: F401

    saved, real = {}, runkit.io.atomic_savefig

    def keep(fig, path, **kw):
        saved[Path(path).name] = [([(ln.get_xdata(), ln.get_ydata()) for ln in ax.lines],
                                   [t.get_text() for t in ax.texts]) for ax in fig.axes]
        return real(fig, path, **kw)

    for name, mod in list(sys.modules.items()):         # every module that imported it
        if name.split(".")[0] in ("runkit", "rheometer", "shear1d", "mpm2d") and getattr(
                mod, "atomic_savefig", None) is real:
            monkeypatch.setattr(mod, "atomic_savefig", keep)
    return saved


def _marked(axes, x: float, words: str, vertical: bool = True) -> int:
    """How many axes carry a line at x (vertical, else horizontal) and a text with ``words``."""
    n = 0
    for lines, texts in axes:
        at = any(len(d) == 2 and np.allclose(np.asarray(d, float), x, rtol=1e-12)
                 for d in (xy[0 if vertical else 1] for xy in lines))
        n += at and any(words in t for t in texts)
    return n


def _limit_crossing(t, tau):
    """Time the granular stress first reaches TAU_LIMIT (linear interpolation)."""
    i = int(np.flatnonzero(np.abs(tau) > TAU_LIMIT)[0])
    return t[i - 1] + (t[i] - t[i - 1]) * (TAU_LIMIT - tau[i - 1]) / (tau[i] - tau[i - 1])


# ------------------------------------------------------------------ rheometer
def test_startup_at_10_per_s_writes_the_transient_up_to_the_jam(tmp_path, monkeypatch, capsys,
                                                                figures):
    """The default material at phi 0.5 shear-jams under 10 1/s and its skeleton then loads
    elastically: the run ends where taubar/G reaches 0.1 (a root of |taubar| - 0.1 G), at the
    time the unlimited algebra crosses it; every row before is written, none past it; exit 3,
    one line, startup.json and startup.png say where and why. A second fraction below phi_c
    (0.42: no jam) runs to its end in the same command."""
    from rheometer import startup
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["startup", "--rate", "10", "--phi", "0.42", "0.5"]) == ENDED_EARLY
    out, err = capsys.readouterr()
    assert "wrote startup.csv" in out and "startup.json" in out
    err = err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("rheometer startup: phi = 0.5: ended early at t = ")
    assert "elastic strain taubar/G reached 0.1" in err[0] and "--G" in err[0]
    df = pd.read_csv("startup.csv")
    full, jam = df[df["phi"] == 0.42], df[df["phi"] == 0.5]
    assert full["time_s"].iloc[-1] == 60.0
    tau = jam["granular_shear_stress_Pa"].to_numpy()
    assert np.all(tau <= TAU_LIMIT * (1 + 1e-9)) and tau[-1] == pytest.approx(TAU_LIMIT, rel=1e-9)
    ref = startup("hermes2016", 0.5, 10.0, 0.05, points=4000)       # no limit: the algebra
    t_end = jam["time_s"].iloc[-1]
    assert t_end == pytest.approx(_limit_crossing(ref["time_s"].to_numpy(),
                                                  ref["granular_shear_stress_Pa"].to_numpy()),
                                  rel=1e-4)
    assert np.interp(jam["time_s"], ref["time_s"], ref["f"]) == pytest.approx(jam["f"], abs=1e-4)
    last = jam.iloc[-33:]                               # the last interval, resampled
    assert np.ptp(np.diff(last["time_s"].to_numpy()[:-1])) < 1e-9 * t_end
    # near the limit the skeleton loads elastically: taubar' = G (gdot - gdot_p), gdot_p << gdot
    rate = np.gradient(last["granular_shear_stress_Pa"], last["time_s"])
    drive = G * (last["shear_rate_per_s"] - last["plastic_shear_rate_per_s"])
    assert rate[1:-2] == pytest.approx(drive.to_numpy()[1:-2], rel=2e-2)
    assert last["plastic_shear_rate_per_s"].iloc[-1] < 0.1 * 10.0
    rec = json.loads(open("startup.json").read())
    assert rec["status"] == "ended_early" and rec["rows"] == len(df)
    (end,) = rec["ends"]
    assert end["run"] == "phi = 0.5" and end["kind"] == "validity_limit"
    assert end["quantity"] == "elastic strain taubar/G" and end["limit"] == 0.1
    assert end["time_s"] == t_end and end["value"] == pytest.approx(0.1, rel=1e-9)
    assert _marked(figures["startup.png"], t_end, "elastic strain taubar/G > 0.1") == 3


def test_program_ramp_line_writes_the_ramp_up_to_the_jam(tmp_path, monkeypatch, capsys, figures):
    """'ramp rate from 0.01 to 100 1/s over 60 s' (log): the rate follows the ramp exactly up
    to the jam at ~31.5 s, where the stress climbs from tens of Pa to the limit within one
    output interval (resampled: 32 rows); the run ends there, exit 3."""
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "ramp.txt").write_text("ramp rate from 0.01 to 100 1/s over 60 s\n")
    assert main(["program", "ramp.txt"]) == ENDED_EARLY
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "rheometer program: phi = 0.5: ended early at t = 31.4" in err[0]
    df = pd.read_csv("program.csv")
    t = df["time_s"].to_numpy()
    assert df["shear_rate_per_s"].to_numpy() == pytest.approx(0.01 * 1e4 ** (t / 60.0),
                                                              rel=10 * 1e-7)   # rtol
    tau = df["granular_shear_stress_Pa"].to_numpy()
    assert np.all(tau <= TAU_LIMIT * (1 + 1e-9)) and tau[-1] == pytest.approx(TAU_LIMIT, rel=1e-9)
    last = t > t[-34]
    assert tau[last].min() < 0.05 * TAU_LIMIT and np.diff(tau[last]).min() > 0
    assert not (tmp_path / "program.checkpoint.npz").exists()
    (end,) = json.loads(open("program.json").read())["ends"]
    assert end["time_s"] == t[-1] and end["kind"] == "validity_limit"
    assert _marked(figures["program.png"], t[-1], "elastic strain taubar/G > 0.1") == 3


def test_a_forced_ida_failure_keeps_the_rows_before_it(tmp_path, monkeypatch, capsys):
    """IDA given too few steps in the second step of a program fails there: the first step's
    rows are written exactly as an unforced run writes them, the second's up to the last
    output time before the failure, the end is a solver failure with IDA's message; exit 3."""
    import rheometer.transient as tr
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.txt").write_text("shear at 1 1/s for 2 s\nshear at 0.2 1/s for 2 s\n")
    argv = ["program", "p.txt", "--phi", "0.42", "--plot", "none"]
    assert main(argv + ["--out", "ref.csv"]) == 0
    capsys.readouterr()
    real, made = tr.Solver, []

    def starved(*a, **kw):
        made.append(1)
        return real(*a, **{**kw, "max_num_steps": 5} if len(made) >= 2 else kw)

    monkeypatch.setattr(tr, "Solver", starved)
    assert main(argv) == ENDED_EARLY
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "ended early at t = " in err[0] and "IDA failed in step 2" in err[0]
    ref, df = pd.read_csv("ref.csv"), pd.read_csv("program.csv")
    one = ref["step"] == 1
    pd.testing.assert_frame_equal(df[df["step"] == 1], ref[one])
    two = df[df["step"] == 2]
    assert 0 < len(two) < (~one).sum()
    pd.testing.assert_frame_equal(two.reset_index(drop=True),
                                  ref[~one].iloc[:len(two)].reset_index(drop=True))
    (end,) = json.loads(open("program.json").read())["ends"]
    assert end["kind"] == "solver_failure" and end["time_s"] == df["time_s"].iloc[-1]
    assert end["past_s"] > end["time_s"] and end["quantity"] == "" and end["limit"] is None


def test_python_api_raises_ended_early_with_the_partial_rows():
    from rheometer import startup

    with pytest.raises(EndedEarly) as exc:
        startup("hermes2016", 0.5, 10.0, 60.0, elastic_limit=True)
    df, (end,) = exc.value.partial, exc.value.ends
    assert df.attrs["end"] == end and end.time_s == df["time_s"].iloc[-1]
    assert str(exc.value) == end.reason and exc.value.written == []


def test_material_point_ends_at_the_step_before_the_limit(tmp_path, monkeypatch, capsys,
                                                         figures):
    """material-point at 50 1/s: the jammed point loads elastically past taubar/G = 0.1 within
    one output interval of 25 steps; the rows are then those of every step up to the last one
    within the limit (the same as a run writing every step), the next step past it."""
    from rheometer import simple_shear_point
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["material-point", "--rate", "50", "--t-end", "10"]) == ENDED_EARLY
    assert "material-point: phi = 0.5: ended early" in capsys.readouterr().err
    df = pd.read_csv("material_point.csv")
    ref = simple_shear_point("hermes2016", 0.5, 50.0, 0.03, 1e-3, points=30)
    n = len(df)
    assert df["time_s"].to_numpy() == pytest.approx(ref["time_s"].to_numpy()[:n], abs=1e-12)
    for col in ("granular_shear_stress_Pa", "granular_pressure_Pa", "N1_Pa", "f"):
        assert df[col].to_numpy() == pytest.approx(ref[col].to_numpy()[:n], rel=1e-9, abs=1e-9)
    tau = ref["granular_shear_stress_Pa"].to_numpy()
    assert tau[n - 1] <= TAU_LIMIT < tau[n]
    (end,) = json.loads(open("material_point.json").read())["ends"]
    assert end["past_s"] == pytest.approx(ref["time_s"].iloc[n]) and end["value"] > 0.1
    assert _marked(figures["material_point.png"], df["time_s"].iloc[-1], "taubar/G > 0.1") == 3


def test_run_command_statuses():
    from runkit.command import FAILED
    from runkit.command import run as run_command

    end = RunEnd("validity_limit", "x past it", 1.0, "elastic strain taubar/G", 0.2, 0.1, 2.0)

    def ended(written):
        def body():
            raise EndedEarly([end], written=written)
        return body

    assert run_command("prog", ended(["a.csv"])) == ENDED_EARLY
    assert run_command("prog", ended([])) == FAILED            # nothing written: a failure
    rec = run_record([end.replace(value=float("nan"))], rows=3)
    assert rec["status"] == "ended_early" and rec["ends"][0]["value"] is None
    json.dumps(rec, allow_nan=False)
    assert run_record([]) == {"status": "complete", "ends": []}
    with pytest.raises(ValueError, match="kind"):
        RunEnd("tired", "")


def test_mark_end_draws_a_line_and_its_label():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    mark_end(ax, 0.4, "ended: solver failure")
    mark_end(ax, 0.7, "ended: limit", vertical=False)
    assert list(ax.lines[1].get_xdata()) == [0.4, 0.4]
    assert list(ax.lines[2].get_ydata()) == [0.7, 0.7]
    assert [t.get_text() for t in ax.texts] == ["ended: solver failure", "ended: limit"]
    plt.close(fig)


# ------------------------------------------------------------------ shear1d
COUETTE = ["couette", "--speed", "1.5", "--gap", "0.001", "--cells", "8", "--time", "3e-4",
           "--outputs", "15", "--method", "explicit", "--quiet"]


def test_shear1d_couette_ends_at_the_first_output_past_the_elastic_limit(tmp_path, capsys,
                                                                         figures):
    """A 1 mm plane Couette gap driven impulsively at 0.1 c_s (its largest speed) jams and its
    skeleton strains past taubar/G = 0.1 at ~0.27 ms: the run ends at the output before; its
    outputs are those of the unlimited run (the explicit scheme, bit for bit), within the limit,
    the next one past it; couette.json says so, couette.png marks it, exit 3."""
    from shear1d.cli import main
    from shear1d.integrate import elastic_strains, solve
    from shear1d.scenes import plane_couette

    out = tmp_path / "c"
    assert main(COUETTE + ["--out", str(out)]) == ENDED_EARLY
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("shear1d couette: couette: ended early at t = ")
    assert "elastic strain taubar/G" in err[0] and "limit 0.1" in err[0]
    rec = json.loads((out / "couette.json").read_text())
    (end,) = rec["ends"]
    assert rec["status"] == "ended_early" and end["kind"] == "validity_limit"
    wall = pd.read_csv(out / "couette_wall.csv")
    n = len(wall)
    assert rec["outputs"] == n and wall["time_s"].iloc[-1] == end["time_s"] == rec["t_end_s"]
    ref = solve(plane_couette(1.5, gap=1e-3, n_cells=8), 3e-4, method="explicit", n_out=15)
    assert n < len(ref.t) and wall["time_s"].to_numpy() == pytest.approx(ref.t[:n], abs=0)
    assert wall["wall_shear_stress_Pa"].to_numpy() == pytest.approx(
        np.abs(ref.field("shear_stress"))[:n, 0], rel=1e-12)
    strains = np.array([elastic_strains(ref.problem, t, y)[0] for t, y in zip(ref.t, ref.y)])
    assert strains[:n].max() <= 0.1 < strains[n]
    assert end["value"] == pytest.approx(strains[n], rel=1e-12) and end["past_s"] == ref.t[n]
    assert _marked(figures["couette.png"], end["time_s"], "elastic strain taubar/G > 0.1") == 1
    assert not list(out.glob("*.npz"))                      # checkpoints removed


def test_shear1d_annular_law_failure_keeps_the_outputs_before_it(tmp_path, monkeypatch, capsys,
                                                                  figures):
    """The Table 8 rate turned to NaN past 5 ms (a forced failure): the local update refuses
    the state inside IDA's residual; the run's outputs before it are written (front, profiles,
    fields, summary with status ended_early and the diagnostics) and agree with the unforced
    run's; the figures are drawn, exit 3."""
    from shear1d.cli import main
    from shear1d.model import Couette

    argv = ["annular", "--u-inner", "0.084", "--mode", "locked", "--cells", "16",
            "--rotation", "0.06", "--outputs", "12", "--quiet"]
    assert main(argv + ["--out", str(tmp_path / "ref")]) == 0
    real = Couette.rhs

    def rhs(self, t, y, out, delta, diag=None):
        real(self, t, y, out, delta, diag)
        if t > 5e-3:
            out[:] = np.nan

    monkeypatch.setattr(Couette, "rhs", rhs)
    out = tmp_path / "run"
    assert main(argv + ["--out", str(out)]) == ENDED_EARLY
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("shear1d annular: u84mm_s_locked: ended early")
    assert "Table 8 local update failed" in err[0] and "in IDA's residual" in err[0]
    tag = "u84mm_s_locked"
    s = json.loads((out / f"{tag}_summary.json").read_text())
    (end,) = s["ends"]
    assert s["status"] == "ended_early" and end["kind"] == "law_failure"
    assert end["time_s"] <= 5e-3 and s["t_end_s"] == end["time_s"]
    front, ref = pd.read_csv(out / f"{tag}_front.csv"), pd.read_csv(tmp_path / "ref" /
                                                                    f"{tag}_front.csv")
    n = len(front)
    assert 2 <= n < len(ref) and front["time_s"].iloc[-1] == end["time_s"]
    for col in ("time_s", "bob_shear_stress_Pa", "bulk_speed_over_u_inner"):
        assert front[col].to_numpy() == pytest.approx(ref[col].to_numpy()[:n], rel=1e-6)
    for name in ("velocity_profiles.png", "front_position.png", f"{tag}_fields.png"):
        assert (out / name).stat().st_size > 10_000
    rot = front["rotation_rad"].iloc[-1]
    assert _marked(figures["front_position.png"], rot, "ended: law failure") == 1
    assert _marked(figures[f"{tag}_fields.png"], rot, "ended: law failure", vertical=False) == 4


# ------------------------------------------------------------------ mpm2d
def test_mpm2d_run_whose_step_fails_ends_there_with_its_history(tmp_path, capsys, monkeypatch):
    """A step failing mid-run (forced at t > 40 % of t_end, the bar scene): the run ends there;
    history.csv holds the rows recorded up to it, equal to an uninterrupted run's; the
    manifest's status is ended_early with the end; one line, exit 3."""
    import mpm2d.scenes
    from mpm2d.cli import main
    from mpm2d.scenes import bar

    argv = ["run", "bar", "--set", "cells=8", "--set", "periods=0.5", "--no-vtk", "--quiet"]
    assert main(argv + ["--out", str(tmp_path / "ref")]) == 0

    def setup(**p):
        sc = bar.setup(**p)

        def before_step(sim, t_fail=0.4 * sc.t_end):
            if sim.t > t_fail:
                raise RuntimeError(f"the local update failed at t = {sim.t:.6g} s (forced)")

        sc.before_step = before_step
        return sc

    setup.spec = bar.setup.spec
    import mpm2d.cli

    monkeypatch.setattr(mpm2d.cli, "get_setup", lambda name: setup)
    out = tmp_path / "run"
    assert main(argv + ["--out", str(out)]) == ENDED_EARLY
    err = [line for line in capsys.readouterr().err.splitlines() if line]
    assert len(err) == 1 and err[0].startswith("mpm2d run: ended early at t = ")
    assert "the local update failed" in err[0] and str(out) in err[0]
    man = json.loads((out / "manifest.json").read_text())
    (end,) = man["ends"]
    assert man["status"] == "ended_early" and end["kind"] == "solver_failure"
    hist, ref = pd.read_csv(out / "history.csv"), pd.read_csv(tmp_path / "ref" / "history.csv")
    n = len(hist)
    assert 1 < n < len(ref) and hist["time_s"].iloc[-1] == end["time_s"]
    t_end = json.loads((tmp_path / "ref" / "manifest.json").read_text())["t_end_s"]
    assert end["past_s"] == end["time_s"] > 0.4 * t_end > hist["time_s"].iloc[-2]
    pd.testing.assert_frame_equal(hist, ref.iloc[:n])
    # the figure of the rows kept, with the end marked (the scene's report needs a whole run)
    assert man["figures"] == ["history.png"]
    img = plt.imread(out / "history.png")
    assert img.ndim == 3 and min(img.shape[:2]) > 200


def test_mpm2d_ended_history_figure_marks_the_end_on_every_panel(tmp_path):
    """plots.ended_history: one panel per numeric column, the last row kept marked on each."""
    from mpm2d.plots import ended_history
    from rheology.run_end import RunEnd

    hist = pd.DataFrame({"time_s": [0.0, 1.0, 2.0], "energy_J": [1.0, 0.9, 0.7],
                         "steps": [0, 10, 20], "case": ["a", "a", "a"]})
    end = RunEnd("solver_failure", "forced", time_s=2.0, past_s=2.5)
    captured = {}
    orig = plt.Figure.savefig

    def keep(fig, *a, **k):
        captured["fig"] = fig
        return orig(fig, *a, **k)

    plt.Figure.savefig = keep
    try:
        ended_history(hist, end, tmp_path / "h.png", "bar")
    finally:
        plt.Figure.savefig = orig
    axes = [ax for ax in captured["fig"].axes if ax.axison]
    assert [ax.get_ylabel() for ax in axes] == ["energy_J", "steps"]
    for ax in axes:
        xs = sorted(line.get_xdata()[0] for line in ax.lines[1:])
        assert xs == [2.0, 2.5]
    assert "ended early (solver_failure) at t = 2.5 s" in captured["fig"]._suptitle.get_text()


def test_shear1d_ida_failure_at_the_first_output_fails_and_leaves_nothing(tmp_path, capsys,
                                                                          monkeypatch):
    """IDA allowed 5 steps cannot reach the first output: nothing to keep, so the run fails
    (exit 1, IDA's diagnostics) and leaves no folder, no checkpoint."""
    import runkit.ida
    from shear1d.cli import main

    real = runkit.ida.IDA
    monkeypatch.setattr(runkit.ida, "IDA", lambda *a, **k: real(*a, **{**k, "max_num_steps": 5}))
    out = tmp_path / "c"
    assert main(COUETTE[:-3] + ["--quiet", "--out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "shear1d couette: failed: IDA failed at t = " in err[0]
    assert "max_num_steps" in err[0] and not out.exists()


def test_resampling_the_end_from_a_restart_point():
    """After a jamming restart the solve that reaches the limit may hold one row (the limit):
    the interval is resolved again from the solve's start (the restart point, the last row of
    the piece before): 32 rows after it, the last on the limit, the same root."""
    import rheometer.transient as tr

    r = tr.Rheometer("hermes2016", 0.5, elastic_limit=True)
    r._points = 300
    step = tr.Step("rate", 10.0, duration=60.0)
    with pytest.raises(EndedEarly) as exc:
        r.run([step])
    df = exc.value.partial
    t_lim = df["time_s"].iloc[-1]
    a = df.iloc[-40]                                       # a restart point before the limit
    st = tr.State(float(a["time_s"]), float(a["granular_shear_stress_Pa"]),
                  float(a["jamming_gap"]), float(a["strain"]))
    last = df.iloc[-1]
    y_lim = np.array([[last["granular_shear_stress_Pa"], last["jamming_gap"],
                       last["plastic_shear_rate_per_s"], last["shear_rate_per_s"],
                       last["strain"]]])
    pieces = [tr._Piece(np.array([t_lim]), y_lim, 0)]
    grid = np.array([st.t, 2 * t_lim, 60.0])
    end = r._resample_end(pieces, step, 0, st, r.control_of(step, r.rest()), r.scales(step, st),
                          grid, None, tr.RunStats())
    t = pieces[0].t
    assert t.size == tr.END_ROWS and t[0] > st.t and end.t == pytest.approx(t_lim, rel=1e-6)
    assert pieces[0].y[-1, tr.TAU] == pytest.approx(TAU_LIMIT, rel=1e-9)
    assert np.all(np.diff(t) > 0)
