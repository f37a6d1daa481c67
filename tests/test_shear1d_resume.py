"""Lost work: checkpoints on interrupt, --resume, and resumed files identical to an
uninterrupted run's (explicit: byte for byte; IDA: within its tolerance)."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from runkit.io import CorruptCheckpoint
from shear1d.cli import main
from shear1d.scenes import run_annular

SPEEDS = (0.00084, 0.084)
KW = dict(n_cells=16, n_out=40, method="explicit", checkpoint_every=1e-9, log=lambda *a, **k: None)


class Stop:
    """A stop hook: raise KeyboardInterrupt at the given output counts (counted over the run)."""

    def __init__(self, *at):
        self.at, self.calls = set(at), 0

    def __call__(self, t):
        self.calls += 1
        if self.calls in self.at:
            raise KeyboardInterrupt


def _files(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def _interrupted_twice(out: Path, first: int, second: int, **kw) -> list[str]:
    """Run, interrupt at output `first`, resume, interrupt again `second` outputs later, resume
    to the end; return the interrupt messages."""
    messages = []
    for hook in (Stop(first), Stop(second)):
        with pytest.raises(KeyboardInterrupt) as exc:
            run_annular(out, SPEEDS, ("locked",), stop_hook=hook, resume=bool(messages),
                        **{**KW, **kw})
        messages.append(str(exc.value))
    run_annular(out, SPEEDS, ("locked",), resume=True, **{**KW, **kw})
    return messages


def test_explicit_solve_killed_twice_is_bit_for_bit_the_uninterrupted_one(tmp_path):
    from shear1d.integrate import solve
    from shear1d.scenes import annular_shear_jamming

    pb, t_end = annular_shear_jamming(0.084, n_cells=16)
    kw = dict(method="explicit", n_out=30, checkpoint=tmp_path / "ck.npz", checkpoint_every=1e9)
    full = solve(pb, t_end, method="explicit", n_out=30)
    for at in (7, 9):                    # the second kill 9 outputs after the resumed start
        with pytest.raises(KeyboardInterrupt, match="ck.npz"):
            solve(pb, t_end, stop_hook=Stop(at), resume=at == 9, **kw)
    again = solve(pb, t_end, resume=True, **kw)
    assert again.t.tobytes() == full.t.tobytes() and again.y.tobytes() == full.y.tobytes()
    assert again.diag.tobytes() == full.diag.tobytes() and again.events == full.events
    assert again.stats == full.stats and full.stats["steps"] > 0


@pytest.mark.slow
def test_explicit_run_killed_twice_writes_the_same_bytes_in_every_file(tmp_path):
    ref, res = tmp_path / "ref", tmp_path / "resumed"
    runs = run_annular(ref, SPEEDS, ("locked",), **KW)
    # first kill in the slow run, second in the fast one (the slow run is then read back)
    msgs = _interrupted_twice(res, 10, 50)
    for msg in msgs:
        assert "checkpoint" in msg and "--resume" in msg, msg
    assert "u0.84mm_s_locked.checkpoint.npz" in msgs[0]
    assert "u84mm_s_locked.checkpoint.npz" in msgs[1]
    a, b = _files(ref), _files(res)
    assert sorted(a) == sorted(b)                      # no checkpoint or temp file left behind
    assert len(a) == 14 and not [n for n in a if n.startswith(".") or "checkpoint" in n]
    for name in a:
        assert a[name] == b[name], name
    s = json.loads((res / "u84mm_s_locked_summary.json").read_text())
    assert s["solver"]["steps"] == runs[1].result.stats["steps"] > 0   # pre-resume steps count
    umask = os.umask(0)
    os.umask(umask)
    for p in res.iterdir():
        assert p.stat().st_mode & 0o777 == 0o666 & ~umask, p


def test_ida_resume_agrees_within_the_tolerance(tmp_path):
    """IDA restarts its BDF history at the checkpoint's output: the resumed run is not the same
    floating-point sequence. Stated tolerance: every CSV value within 2e-3 of its column's scale
    (velocities in u_i, stresses in their maximum), the front speed within 1 %."""
    kw = dict(KW, method="ida")
    ref, res = tmp_path / "ref", tmp_path / "resumed"
    run_annular(ref, SPEEDS[1:], ("locked",), **kw)
    with pytest.raises(KeyboardInterrupt):
        run_annular(res, SPEEDS[1:], ("locked",), stop_hook=Stop(15), **kw)
    run_annular(res, SPEEDS[1:], ("locked",), resume=True, **kw)
    assert sorted(_files(ref)) == sorted(_files(res))
    worst = 0.0
    for name in ("u84mm_s_locked_velocity_profiles.csv", "u84mm_s_locked_cell_profiles.csv",
                 "u84mm_s_locked_fields.csv"):
        x, y = pd.read_csv(ref / name), pd.read_csv(res / name)
        for col in x.columns:
            scale = max(np.abs(x[col]).max(), 1e-300)
            worst = max(worst, float(np.max(np.abs(x[col] - y[col])) / scale))
    assert worst < 2e-3, worst
    sa, sb = (json.loads((d / "u84mm_s_locked_summary.json").read_text()) for d in (ref, res))
    assert abs(sb["front_speed_m_per_s"] / sa["front_speed_m_per_s"] - 1) < 0.01


def test_corrupt_checkpoint_falls_back_to_the_previous_one_or_is_named(tmp_path):
    ref, res = tmp_path / "ref", tmp_path / "resumed"
    run_annular(ref, SPEEDS[1:], ("locked",), **KW)
    with pytest.raises(KeyboardInterrupt):
        run_annular(res, SPEEDS[1:], ("locked",), stop_hook=Stop(20), **KW)
    ck = res / "u84mm_s_locked.checkpoint.npz"
    prev = res / "u84mm_s_locked.checkpoint.prev.npz"
    assert ck.is_file() and prev.is_file()
    ck.write_bytes(b"garbage")
    said = []
    run_annular(res, SPEEDS[1:], ("locked",), resume=True,
                **{**KW, "log": lambda *a, **k: said.append(" ".join(map(str, a)))})
    assert any("corrupt" in str(m) and str(prev) in str(m) for m in said), said
    assert _files(ref) == _files(res)                  # one output earlier, same bytes
    with pytest.raises(KeyboardInterrupt):
        run_annular(res, SPEEDS[1:], ("locked",), stop_hook=Stop(20), **KW)
    ck.write_bytes(b"garbage")
    prev.write_bytes(b"garbage too")
    with pytest.raises(CorruptCheckpoint, match="corrupt"):
        run_annular(res, SPEEDS[1:], ("locked",), resume=True, **KW)


def test_resume_without_a_checkpoint_is_refused_and_writes_nothing(tmp_path, capsys):
    out = tmp_path / "none"
    assert main(["annular", "--u-inner", "0.084", "--cells", "16", "--resume", "--quiet",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no checkpoint" in err[0], err
    assert not out.exists()
    assert main(["couette", "--speed", "0.01", "--resume", "--out", str(out)]) == 2
    assert not out.exists()


def test_interrupt_says_resume_only_when_a_checkpoint_exists(tmp_path, capsys, monkeypatch):
    import shear1d.scenes as scenes

    def no_run(*a, **k):
        raise KeyboardInterrupt
    monkeypatch.setattr(scenes, "integrate", no_run)
    assert main(["annular", "--u-inner", "0.084", "--cells", "16", "--quiet",
                 "--out", str(tmp_path / "a")]) == 130
    err = capsys.readouterr().err.strip()
    assert "nothing was saved" in err and "--resume" not in err, err
    monkeypatch.undo()
    with pytest.raises(KeyboardInterrupt, match="checkpoint .*u84mm_s_locked.*--resume"):
        run_annular(tmp_path / "b", SPEEDS[1:], ("locked",), stop_hook=Stop(3), **KW)


@pytest.mark.slow
def test_sigterm_then_resume_gives_the_uninterrupted_files(tmp_path):
    """A real SIGTERM to the command (not the programmatic hook), twice, then --resume."""
    args = [sys.executable, "-m", "shear1d", "annular", "--u-inner", "0.00084", "0.084",
            "--mode", "locked", "--cells", "60", "--outputs", "60", "--method", "explicit",
            "--checkpoint-every", "0.05", "--quiet"]
    ref, res = tmp_path / "ref", tmp_path / "res"
    subprocess.run(args + ["--out", str(ref)], check=True, capture_output=True, timeout=600)
    for kill in range(2):
        proc = subprocess.Popen(args + ["--out", str(res)] + (["--resume"] if kill else []),
                                stderr=subprocess.PIPE, text=True)
        ck = res / ("u0.84mm_s_locked.checkpoint.npz" if kill == 0
                    else "u84mm_s_locked.checkpoint.npz")
        t0 = time.time()
        while not ck.exists() and proc.poll() is None and time.time() - t0 < 300:
            time.sleep(0.05)
        time.sleep(0.3)
        proc.send_signal(signal.SIGTERM)
        err = proc.communicate(timeout=300)[1]
        assert proc.returncode == 130, err
        assert "checkpoint" in err and "--resume" in err, err
    subprocess.run(args + ["--out", str(res), "--resume"], check=True, capture_output=True,
                   timeout=600)
    a, b = _files(ref), _files(res)
    assert sorted(a) == sorted(b)
    for name in a:
        assert a[name] == b[name], name
