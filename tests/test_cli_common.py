"""runkit.command.OneLineParser: a negative number given as a separate word is a value.

argparse's own matcher reads only ``-1`` and ``-.5`` as negative numbers; ``--G -1e4``,
``--G -inf`` or ``--frames -3e0`` became "expected one argument" with no range. Every CLI's
parser and subparsers (``parser_class=OneLineParser``) now hand such words to the option's
``Number``, which names the option and its range.
"""

from __future__ import annotations

import argparse

import pytest

from runkit.command import NEGATIVE_NUMBER, OneLineParser
from runkit.params import Number


@pytest.mark.parametrize("word", ["-1", "-.5", "-1.", "-1e4", "-1E4", "-1.5e-3", "-.5e+2",
                                  "-inf", "-Inf", "-infinity", "-nan", "-NaN"])
def test_negative_numbers_are_values(word):
    assert NEGATIVE_NUMBER.match(word)
    p = OneLineParser(prog="t")
    sub = p.add_subparsers(dest="cmd", parser_class=OneLineParser)
    s = sub.add_parser("run")
    s.add_argument("--x", type=str)
    assert s.parse_args(["--x", word]).x == word


@pytest.mark.parametrize("word", ["-x", "--x", "-e4", "-1e", "-", "-1-2", "-infx"])
def test_option_like_words_are_not_numbers(word):
    assert not NEGATIVE_NUMBER.match(word)


def _run(argv, tmp_path, monkeypatch, capsys):
    import importlib

    monkeypatch.chdir(tmp_path)
    main = importlib.import_module(f"{argv[0]}.cli").main
    try:
        status = main(argv[1:])
    except SystemExit as exc:
        status = exc.code
    err = capsys.readouterr().err
    assert status == 2, (argv, err)
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert not any(tmp_path.iterdir()), list(tmp_path.iterdir())
    return err


@pytest.mark.parametrize("argv, match", [
    (["rheometer", "relax", "--G", "-1e4"], "--G = -1e4 is outside the valid range [1, 1e+12] Pa"),
    (["rheometer", "relax", "--G", "-inf"], "--G = -inf: must be finite; valid range [1, 1e+12]"),
    (["rheometer", "startup", "--rate", "-1e-3"],
     "--rate = -0.001 is outside the valid range [1e-09, 1e+09] 1/s, or 0"),
    (["rheometer", "flow-curve", "--phi", "0.5", "-1e-2"],
     # was (0, 0.535) (an arithmetic bottom 0): now the dilute limit PHI_MIN with its reason
     "--phi = -0.01 is outside the valid range [1e-06, 0.535) (one grain volume in 1e6"),
    (["rheometer", "relax", "--phi", "-nan"], "--phi = -nan: must be finite"),
    (["shear1d", "couette", "--speed", "-1e-2"],
     "--speed = -0.01 is outside the valid range [1e-18, 1.53156] m/s (a molecular size"),
    (["shear1d", "annular", "--u-inner", "-1E3"],
     "--u-inner = -1000 is outside the valid range [1e-18, 1.53156] m/s"),   # the material's
    (["mpm2d", "run", "bar", "--frames", "-3"], "--frames = -3 is outside the valid range"),
    (["mpm2d", "run", "bar", "--frames", "-3e0"], "--frames = -3e0 is outside the valid range"),
])
def test_negative_word_gets_the_options_range(argv, match, tmp_path, monkeypatch, capsys):
    err = _run(argv, tmp_path, monkeypatch, capsys)
    assert match in err and "expected one argument" not in err


def test_number_type_still_refuses_through_argparse():
    p = OneLineParser(prog="t")
    p.add_argument("--n", type=Number("--n", 0, 10))
    assert p.parse_args(["--n", "5e0"]).n == 5.0
    with pytest.raises(SystemExit):
        p.parse_args(["--n", "-5e0"])
    assert isinstance(p, argparse.ArgumentParser)


def test_number_refuses_subnormals_and_shows_values_unrounded():
    """A nonzero value below the smallest normal double is held with lost precision (a creep at
    1e-320 Pa gave a wrong viscosity): refused by name; a float that 6 digits would round onto the
    bound is shown in full, so the message does not contradict itself."""

    n = Number("--stress", 0.0, 1e12, lo_closed=False, unit="Pa")
    with pytest.raises(ValueError, match=r"--stress = 1e-320 is subnormal"):
        n.check("1e-320")
    with pytest.raises(ValueError, match=r"outside the valid range \(0, 1e\+12\] Pa"):
        n.check("1e-400")                           # 0 once parsed: the range says so
    assert n.check("3e-308") == 3e-308
    top = Number("--speed", 0.0, 1.5315603, lo_closed=False, unit="m/s")
    with pytest.raises(ValueError, match=r"--speed = 1\.531561 is outside"):
        top.check(1.531561)


def test_extreme_rate_range_is_refused_not_a_traceback(capsys):
    """--rate-range 1e-300 1 overflowed hi/lo in the steady solver's grid (OverflowError), later
    ran for minutes: now refused at once while the options are read, naming the option and its
    range (rheometer.limits: no steady state below 1e-9 1/s within TIME_MAX)."""
    from rheometer.cli import main

    with pytest.raises(SystemExit) as exc:
        main(["flow-curve", "--control", "rate", "--rate-range", "1e-300", "1", "--points", "5",
              "--plot", "none", "--out", "/nonexistent_dir_for_test/x.csv"])
    err = capsys.readouterr().err.strip().splitlines()
    assert exc.value.code == 2 and len(err) == 1, err
    assert "--rate-range = 1e-300" in err[0] and "[1e-09" in err[0], err


def test_run_command_turns_an_arithmetic_error_into_one_failure_line(capsys):
    """The last net under the tiers' checks: an OverflowError from a library (rheometer fit
    --f-scale 1e300 reached scipy) is one 'failed' line, exit 1, no traceback."""
    from runkit.command import FAILED
    from runkit.command import run as run_command

    def body():
        raise OverflowError(34, "Numerical result out of range")

    assert run_command("demo", body) == FAILED
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["demo: failed: OverflowError: (34, 'Numerical result out of range')"], err


def test_run_command_passes_stdout_unchanged_and_ida_takes_sundials_lines(capsys):
    """A command's own lines (blank lines and a partial last line too) reach stdout as written;
    SUNDIALS' error lines printed inside an IDA call are taken by runkit.ida.captured, which
    every solver call goes through (one mechanism), and carried by the failure's message."""
    from runkit.command import run as run_command
    from runkit.ida import captured

    def body():
        for text in ("shear1d: run ...\n", "\n", "partial", " line\n", "\n", "end"):
            print(text, end="")
        with captured() as c:
            print("\n[IDASolve, Error: -22] At t = 1, mxstep.\n")
        assert c.text == "[IDASolve, Error: -22] At t = 1, mxstep."

    assert run_command("demo", body) == 0
    assert capsys.readouterr().out == "shear1d: run ...\n\npartial line\n\nend"


@pytest.mark.parametrize("argv", [
    ["-c", "from runkit.command import run\n"
           "raise SystemExit(run('demo', lambda: print('x' * 100000)))"],
    ["-c", "from rheometer.cli import main\nraise SystemExit(main(['materials']))"],
])
def test_a_closed_stdout_ends_silently_with_the_sigpipe_status(argv):
    """``rheometer materials | head -1``: the reader gone, the command ends with 141 (128 +
    SIGPIPE, as cat or seq) and nothing on stderr (it printed 'failed: [Errno 32] Broken pipe',
    exit 1, and a traceback when the pipe broke at the interpreter's last flush)."""
    import os
    import subprocess
    import sys

    from runkit.command import BROKEN_PIPE

    read, write = os.pipe()
    os.close(read)                              # the reader is gone before the first line
    try:
        done = subprocess.run([sys.executable, *argv], stdout=write, stderr=subprocess.PIPE,
                              text=True, timeout=120)
    finally:
        os.close(write)
    assert (done.returncode, done.stderr) == (BROKEN_PIPE, ""), done.stderr
