"""Runs that end early keep their rows up to the end (rheology.run_end): rheometer transients
at the elastic-strain limit or a solver failure, shear1d and mpm2d runs likewise.

Each test checks the physics of the rows kept (the limit reached and never passed, the rows the
unlimited run computes at the same times, the imposed ramp), the end record, the console line,
the exit status 3 and the mark on the figure."""

import json

import numpy as np
import pandas as pd
import pytest

from rheology.elastic import ELASTIC_STRAIN_LIMIT
from rheology.run_end import ENDED_EARLY, EndedEarly, RunEnd, mark_end, run_record

G = 1.0e4                     # the transients' default modulus (hermes2016 has none)
TAU_LIMIT = ELASTIC_STRAIN_LIMIT * G


@pytest.fixture
def figures(monkeypatch):
    """The figures the commands save (through rheology.io.atomic_savefig), by path."""
    import rheology.io

    saved, real = {}, rheology.io.atomic_savefig

    def keep(fig, path, **kw):
        saved[str(path)] = [(ax.get_xlabel(), [ln.get_xdata() for ln in ax.lines],
                             [t.get_text() for t in ax.texts]) for ax in fig.axes]
        return real(fig, path, **kw)

    monkeypatch.setattr(rheology.io, "atomic_savefig", keep)
    return saved


def _marked(axes, x: float, words: str) -> int:
    """How many axes carry a vertical line at x and a text with ``words``."""
    n = 0
    for _, lines, texts in axes:
        vertical = any(len(d) == 2 and np.allclose(np.asarray(d, float), x, rtol=1e-12)
                       for d in lines)
        n += vertical and any(words in t for t in texts)
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
    real, made = tr.IDA, []

    def starved(*a, **kw):
        made.append(1)
        return real(*a, **{**kw, "max_num_steps": 5} if len(made) >= 2 else kw)

    monkeypatch.setattr(tr, "IDA", starved)
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
    from rheology.cli_common import FAILED, run_command

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
