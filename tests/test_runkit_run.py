"""runkit.run and runkit.command: a run interrupted (by a signal, or stopped) and resumed is the
uninterrupted run bit for bit; a checkpoint of another run is refused by its difference; held
numpy warnings; progress lines off a terminal; the output-folder policy; the exit statuses."""

from __future__ import annotations

import io
import json
import os
import signal
import warnings

import numpy as np
import pytest

from runkit.command import ENDED_EARLY, FAILED, INTERRUPTED, USAGE, OneLineParser, run
from runkit.run import (CHECKPOINT, Checkpoint, Folder, HeldWarnings, Progress, drive,
                         retire_checkpoints, table_arrays, table_rows)

OMEGA = 2.0 * np.pi                       # [rad/s]


class Oscillator:
    """x'' = -omega^2 x by symplectic Euler with step dt: its discrete energy
    E = v^2 + omega^2 x^2 - omega^2 dt x v is conserved exactly (to roundoff)."""

    def __init__(self, dt=1e-3, t_end=2.0, signal_at=None):
        self.t, self.t_end, self.steps, self.dt = 0.0, t_end, 0, dt
        self.x, self.v, self.signal_at = 1.0, 0.0, signal_at
        self.history = []

    def advance(self):
        self.v -= self.dt * OMEGA ** 2 * self.x
        self.x += self.dt * self.v
        self.t += self.dt
        self.steps += 1
        self.history.append(self.x)
        if self.steps == self.signal_at:
            os.kill(os.getpid(), signal.SIGTERM)          # arrives inside the step

    def state(self):
        return {"t": np.array(self.t), "x": np.array(self.x), "v": np.array(self.v),
                "steps": np.array(self.steps), "history": np.array(self.history)}

    def load(self, s):
        self.t, self.x, self.v = float(s["t"]), float(s["x"]), float(s["v"])
        self.steps, self.history = int(s["steps"]), list(s["history"])

    def energy(self):
        return self.v ** 2 + OMEGA ** 2 * self.x ** 2 - OMEGA ** 2 * self.dt * self.x * self.v


FP = {"scene": "oscillator", "dt": 1e-3, "t_end": 2.0}


def test_the_discrete_energy_is_conserved():
    o = Oscillator()
    e0 = o.energy()
    assert drive(o) is True and o.steps == 2000
    assert o.energy() == pytest.approx(e0, rel=1e-12)


def test_a_signal_is_deferred_to_the_end_of_the_step_and_the_resume_is_bit_for_bit(tmp_path):
    ref = Oscillator()
    drive(ref)
    ck = Checkpoint(tmp_path / "run.checkpoint.npz", FP)
    o = Oscillator(signal_at=700)
    with pytest.raises(KeyboardInterrupt, match="checkpoint written to .* at t = 0.7 s"):
        drive(o, checkpoint=ck, every=1e9)
    assert o.steps == 700                              # stopped between steps, not inside one
    again = Oscillator()
    again.load(ck.load())
    assert again.steps == 700
    assert drive(again, checkpoint=ck) is True
    assert again.history == ref.history and (again.x, again.v) == (ref.x, ref.v)


def test_stop_after_then_resume_through_a_corrupt_checkpoint_is_bit_for_bit(tmp_path):
    ref = Oscillator()
    drive(ref)
    ck = Checkpoint(tmp_path / "c.npz", FP)
    o = Oscillator()
    assert drive(o, checkpoint=ck, stop_after=300) is False
    drive(o, checkpoint=ck, stop_after=300)            # a second checkpoint: the first kept
    ck.path.write_bytes(b"not an npz")
    logged = []
    again = Oscillator()
    again.load(ck.load(log=logged.append))             # falls back to the kept predecessor
    assert again.steps == 300 and "corrupt" in logged[0]
    drive(again)
    assert again.history == ref.history


def test_a_checkpoint_of_another_run_is_refused_by_its_difference(tmp_path):
    ck = Checkpoint(tmp_path / "c.npz", FP)
    drive(Oscillator(), checkpoint=ck, stop_after=5)
    other = Checkpoint(tmp_path / "c.npz", {**FP, "dt": 2e-3})
    with pytest.raises(ValueError, match=r"--resume: dt = 0.002 differs from the checkpoint's "
                                         r"dt = 0.001"):
        other.load()
    ck.remove()
    assert not ck.exists()
    with pytest.raises(ValueError, match="no checkpoint"):
        ck.load()


def test_a_failure_cites_numpy_s_first_warning_and_a_success_shows_them():
    class Diverging(Oscillator):
        def advance(self):
            super().advance()
            np.float64(1e308) * 10.0                 # overflow: a RuntimeWarning
            if self.steps == 3:
                raise RuntimeError("non-finite energy at step 3")

    with pytest.raises(RuntimeError, match=r"non-finite energy at step 3 after numpy's "
                                           r"'overflow encountered"):
        drive(Diverging())
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with HeldWarnings() as held:
            np.float64(1e308) * 10.0
        assert not seen                               # held while open
        held.replay()
    assert any("overflow" in str(w.message) for w in seen)


def test_progress_off_a_terminal_is_plain_lines():
    out = io.StringIO()
    p = Progress(0.0, 0.01, label="osc", stream=out, every=0.0)
    drive(Oscillator(t_end=0.01), progress=p)
    lines = out.getvalue().splitlines()
    assert len(lines) >= 2 and lines[-1].startswith("osc: 100.0% t = 0.01/0.01 s, step 10")
    assert "\r" not in out.getvalue()


def test_the_folder_policy(tmp_path):
    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("keep")
    with pytest.raises(ValueError, match="non-empty folder that holds no mpm2d run"):
        Folder(user, "mpm2d").prepare()
    assert (user / "notes.txt").read_text() == "keep"
    out = tmp_path / "run"
    f = Folder(out, "mpm2d")
    assert f.prepare() == []
    for name in ("history.csv", "frames/frame_00000.npz"):
        (out / name).parent.mkdir(exist_ok=True)
        (out / name).write_text("x")
        f.wrote(out / name)
    f.write_manifest("complete")
    (out / "mine.txt").write_text("the user's")            # not ours: kept
    (out / ".history.csv.abcd1234.tmp").write_text("")     # a killed atomic write
    again = Folder(out, "mpm2d")
    gone = again.prepare()
    assert sorted(gone) == [".history.csv.abcd1234.tmp", "frames/frame_00000.npz",
                            "history.csv", "manifest.json"]
    assert (out / "mine.txt").exists()
    again.write_manifest("failed", error="diverged")
    assert json.loads((out / "manifest.json").read_text())["status"] == "failed"
    resumed = Folder(out, "mpm2d")
    resumed.prepare(resume=True)
    assert resumed.manifest["status"] == "running" and resumed.manifest["error"] == "diverged"


def test_a_completed_run_keeps_no_checkpoint_an_interrupted_one_does(tmp_path):
    """Folder.write_manifest('complete') removes the folder's checkpoint and its predecessor;
    retire_checkpoints removes those of the completed runs under a folder (the validation
    report's run folders, the mpm2d runner keeping a completed run's) and keeps the others."""
    runs = {}
    for name, status in (("done", "complete"), ("stopped", "stopped"), ("killed", "running"),
                         ("failed", "failed"), ("nested/done", "complete")):
        out = runs[name] = tmp_path / name
        f = Folder(out, "mpm2d")
        f.prepare()
        ck = Checkpoint(out / CHECKPOINT, FP)
        o = Oscillator(t_end=0.01)
        drive(o, checkpoint=ck, every=0.0)             # a checkpoint and its predecessor
        assert (out / CHECKPOINT).is_file() and (out / "checkpoint.prev.npz").is_file()
        atomic = out / "manifest.json"
        atomic.write_text(json.dumps({**f.manifest, "status": status}))
    gone = retire_checkpoints(tmp_path)
    assert sorted(str(p.relative_to(tmp_path)) for p in gone) == [
        "done/checkpoint.npz", "done/checkpoint.prev.npz", "nested/done/checkpoint.npz",
        "nested/done/checkpoint.prev.npz"]
    for name in ("stopped", "killed", "failed"):
        assert (runs[name] / CHECKPOINT).is_file(), name
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "manifest.json").write_text("[not json")
    assert retire_checkpoints(tmp_path) == []
    f = Folder(runs["stopped"], "mpm2d")
    f.prepare(resume=True)
    f.write_manifest("stopped")
    assert (runs["stopped"] / CHECKPOINT).is_file()
    f.write_manifest("complete")
    assert not list(runs["stopped"].glob("checkpoint*"))


class _Ended(RuntimeError):
    def __init__(self):
        super().__init__("elastic strain past 0.1")

        class End:
            def line(self):
                return "ended early at t = 1 s (last row written): elastic strain past 0.1"

        self.ends, self.written = [End()], ["out.csv"]


@pytest.mark.parametrize("exc, status, line", [
    (ValueError("--x = 1 is outside the valid range [2, 3]"), USAGE,
     "p: error: --x = 1 is outside the valid range [2, 3]"),
    (RuntimeError("IDA failed\nat t = 1 s"), FAILED, "p: failed: IDA failed at t = 1 s"),
    (ZeroDivisionError("division by zero"), FAILED, "p: failed: ZeroDivisionError: division"),
    (_Ended(), ENDED_EARLY, "p: ended early at t = 1 s (last row written): elastic strain"),
    (KeyboardInterrupt(), INTERRUPTED, "p: interrupted (rerun with --resume)"),
])
def test_exit_statuses_and_one_line(exc, status, line, capsys):
    def body():
        raise exc

    assert run("p", body, on_interrupt="rerun with --resume") == status
    err = capsys.readouterr().err
    assert err.startswith(line) and err.count("\n") == 1


def test_sigterm_is_an_interrupt_and_negative_numbers_are_values(capsys):
    assert run("p", lambda: os.kill(os.getpid(), signal.SIGTERM)) == INTERRUPTED
    assert capsys.readouterr().err == "p: interrupted\n"
    p = OneLineParser(prog="t")
    p.add_argument("--g", type=float)
    assert p.parse_args(["--g", "-1e4"]).g == -1e4
    with pytest.raises(SystemExit) as e:
        p.parse_args(["--nope"])
    assert e.value.code == USAGE
    assert capsys.readouterr().err.count("\n") == 1


def test_a_table_in_a_checkpoint_comes_back_with_its_types(tmp_path):
    """table_arrays/table_rows: a run's history saved column by column (an integer column stays
    integer) reads back as the same rows of Python values."""
    rows = [{"time_s": 0.0, "step": 0, "total_J": 1.5},
            {"time_s": 0.25, "step": 7, "total_J": 2.0}]
    arrays = table_arrays(rows, "run.history")
    assert arrays["run.history.1"].dtype.kind == "i"
    ck = Checkpoint(tmp_path / CHECKPOINT, FP)
    ck.save(arrays)
    back = table_rows(ck.load(), "run.history")
    assert back == rows and all(type(r["step"]) is int for r in back)


class _Snapshots(Folder):
    """A tier's folder: its manifest marked by 'scene', its files under frames/ only."""

    subdirs = ("frames",)
    keeps_checkpoint = True

    def ours(self, manifest):
        return isinstance(manifest.get("scene"), str)

    def listed(self, manifest):
        return [*manifest["written"], "manifest.json", "../outside.txt", "elsewhere/x.npz"]


def test_a_folder_with_fields_of_its_own(tmp_path):
    """Folder's hooks: ours() recognises the tier's manifest, listed() names what it wrote (a
    name outside the folder or its subdirs is never trusted), a folder outside subdirs is the
    user's, keeps_checkpoint keeps a completed run's checkpoint."""
    (tmp_path / "outside.txt").write_text("keep")
    out = tmp_path / "run"
    (out / "elsewhere").mkdir(parents=True)
    with pytest.raises(ValueError, match="holds no snapshots run"):
        _Snapshots(out, "snapshots").check()                 # an empty folder of the user's
    (out / "elsewhere").rmdir()
    f = _Snapshots(out, "snapshots")
    assert f.prepare() == []
    f.manifest = {"scene": "s", "written": ["frames/a.npz"], "status": "running"}
    (out / "frames").mkdir()
    for name in ("frames/a.npz", CHECKPOINT):
        (out / name).write_text("x")
    f.write_manifest("complete")
    assert (out / CHECKPOINT).is_file()
    (out / "elsewhere").mkdir()
    (out / "elsewhere" / "x.npz").write_text("the user's")
    assert sorted(_Snapshots(out, "snapshots").prepare()) == ["frames/a.npz", "manifest.json"]
    assert (out / "elsewhere" / "x.npz").is_file() and (tmp_path / "outside.txt").is_file()
