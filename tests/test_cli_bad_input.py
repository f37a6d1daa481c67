"""Every numeric option of every subcommand of every CLI refuses bad values the same way.

The mechanism is ``runkit.params.Number``: every option that takes a number declares it as
its argparse ``type`` with the valid range. This test walks the parsers (so a new option is covered
the day it is added), fails on any numeric option that bypasses ``Number``, and draws bad values
(NaN, inf, out of range, not a number, huge) for each: the command must exit with status 2 and
one line on stderr that names the option and the valid range, and write nothing.
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
from unittest import mock

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from runkit.params import Number

#: console script -> module with ``main(argv)``
CLIS = {"rheometer": "rheometer.cli", "shear1d": "shear1d.cli", "mpm2d": "mpm2d.cli"}
#: arguments a subcommand needs besides the option under test
REQUIRED = {("shear1d", "couette"): ["--speed", "0.01"], ("mpm2d", "run"): ["bar"],
            ("mpm2d", "show"): ["bar"], ("mpm2d", "sweep"): ["bar"]}


class _Grabbed(Exception):
    pass


def _parser(cli):
    """The module and the top-level parser its ``main`` builds (caught at ``parse_args``)."""
    mod = importlib.import_module(CLIS[cli])
    grabbed = {}

    def grab(self, *args, **kwargs):
        grabbed["parser"] = self
        raise _Grabbed

    with mock.patch.object(argparse.ArgumentParser, "parse_args", grab):
        try:
            mod.main([])
        except _Grabbed:
            pass
    return mod, grabbed["parser"]


def _subcommands(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            yield from action.choices.items()


def _options():
    out = []
    for cli in CLIS:
        _, parser = _parser(cli)
        for sub, sp in _subcommands(parser):
            for action in sp._actions:
                if not action.option_strings or action.nargs == 0:
                    continue
                out.append((cli, sub, action))
    return out


OPTIONS = _options()
NUMERIC = [(cli, sub, a) for cli, sub, a in OPTIONS if isinstance(a.type, Number)]


def test_every_numeric_option_uses_number():
    """No option parses numbers with bare float/int (those accept nan and inf)."""
    bare = [f"{cli} {sub} {a.option_strings[-1]}" for cli, sub, a in OPTIONS
            if a.type in (float, int)]
    assert not bare, f"options bypassing runkit.params.Number: {bare}"
    assert len(NUMERIC) >= 20          # the walk found the options (guards an empty walk)


def _bad_values(number: Number):
    cands = ["nan", "NaN", "inf", "-inf", "1e400", "abc", "", "0x", "-1", "0", "-1e300", "1e300"]
    if number.lo is not None:
        cands += [repr(number.lo - 1.0), repr(number.lo - abs(number.lo) * 0.5 - 1e-9)]
        if not number.lo_closed:
            cands.append(repr(float(number.lo)))
    if number.hi is not None:
        cands += [repr(number.hi * 2 + 1.0), repr(number.hi + 1.0)]
        if not number.hi_closed:
            cands.append(repr(float(number.hi)))
    if number.integer:
        cands += ["1.5", "2.25"]

    def bad(text):
        try:
            x = float(text)
        except ValueError:
            return True
        return not number.contains(x) or not math.isfinite(x)
    return sorted({c for c in cands if bad(c)})


CASES = [(cli, sub, a.option_strings[-1], v) for cli, sub, a in NUMERIC
         for v in _bad_values(a.type)]


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=st.sampled_from(CASES))
def test_bad_value_is_one_line_exit_2_nothing_written(case, tmp_path_factory, capsys):
    cli, sub, option, value = case
    mod, parser = _parser(cli)
    action = next(a for a in dict(_subcommands(parser))[sub]._actions
                  if option in a.option_strings)
    nargs = action.nargs if isinstance(action.nargs, int) else 1
    work = tmp_path_factory.mktemp("bad")
    cwd = os.getcwd()
    os.chdir(work)
    try:
        argv = [sub, *REQUIRED.get((cli, sub), []), f"{option}={value}" if nargs == 1 else option]
        if nargs != 1:
            argv += [value] * nargs
        try:
            status = mod.main(argv)
        except SystemExit as exc:
            status = exc.code
    finally:
        os.chdir(cwd)
    err = capsys.readouterr().err.strip()
    assert status == 2, (argv, status, err)
    assert len(err.splitlines()) == 1, err
    assert option in err, err
    assert not any(work.iterdir()), f"{argv} wrote {list(work.iterdir())}"


@pytest.mark.parametrize("cli", sorted(CLIS))
def test_help_of_every_subcommand(cli, capsys):
    """--help works for every subcommand (status 0) and names each numeric range nowhere wrongly."""
    mod, parser = _parser(cli)
    for sub, _ in _subcommands(parser):
        with pytest.raises(SystemExit) as exc:
            mod.main([sub, "--help"])
        assert exc.value.code == 0
    assert capsys.readouterr().out


def test_unwritable_outputs_are_refused_before_any_work(tmp_path):
    """An output under a folder where nothing can be created (or a file where a folder is
    needed) is refused with one line naming the option, before anything runs or is written."""
    from runkit.io import check_output_dir, check_output_path

    with pytest.raises(ValueError, match="--plot = '/proc/x.png': cannot write in /proc"):
        check_output_path("--plot", "/proc/x.png", ["figure"])
    with pytest.raises(ValueError, match="trailing separator"):
        check_output_path("--out", f"{tmp_path}/d.csv/", ["csv"])
    assert not (tmp_path / "d.csv").exists()
    afile = tmp_path / "afile"
    afile.write_text("x")
    with pytest.raises(ValueError, match="exists and is not a folder"):
        check_output_dir("--out", afile)
    with pytest.raises(ValueError, match="is a file, not a folder"):
        check_output_dir("--out", afile / "sub")
    assert check_output_dir("--out", tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    assert not (tmp_path / "new").exists() and sorted(tmp_path.iterdir()) == [afile]


# ---------------------------------------------------------------- a --set the Material refuses
@pytest.mark.parametrize("argv, words", [
    # phi_j = 0.3 was refused as "phi_c = 0.436 is outside the valid range (0, 0.3)"
    (["flow-curve", "--set", "phi_j=0.3"],
     "--set phi_j = 0.3 is outside the valid range (0.436, 1)"),
    (["materials", "--material", "hermes2016", "--set", "phi_j=0.3"],
     "--set phi_j = 0.3 is outside the valid range (0.436, 1)"),
    # the static bound found by the same search (0 < phi_j < 1), tightened by phi_c
    (["flow-curve", "--set", "phi_j=1.5"], "--set phi_j = 1.5 is outside the valid range "
                                           "(0.436, 1)"),
    # a_inf >= a0 = 0.8 (closed), mu_2 >= mu_c
    (["flow-curve", "--set", "a_inf=0.5"], "--set a_inf = 0.5 is outside the valid range [0.8, "
                                           "inf)"),
    (["startup", "--set", "mu_c=5", "--set", "mu_2=2"], "--set mu_c = 5 is outside the valid "
                                                        "range (0, 2]"),
])
def test_rheometer_set_refusal_names_the_parameter_set(argv, words, tmp_path, monkeypatch,
                                                       capsys):
    """A --set the Material refuses through another parameter's bound is said about the
    parameter set, with its valid range at the material's other values; nothing written."""
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not any(tmp_path.iterdir())


def test_valid_interval_finds_the_bounds():
    """runkit.params.valid_interval on checks with known bounds: open/closed, 0 and unbounded."""
    from runkit.params import valid_interval

    assert valid_interval(lambda x: 0.25 < x <= 0.75, 0.5) == (0.25, False, 0.75, True)
    assert valid_interval(lambda x: x > 0, 3.0) == (0.0, False, None, True)
    assert valid_interval(lambda x: -2.0 <= x < 1e300, 1.0) == (-2.0, True, 1e300, False)


@pytest.mark.parametrize("argv, words", [
    (["flow-curve", "--phi", "0.48", "0.48"], "--phi 0.48 is given twice"),
    (["flow-curve", "--mass-fraction", "0.5", "0.5"], "--mass-fraction 0.5 is given twice"),
    (["flow-curve", "--control", "rate", "--stress-range", "1", "10"],
     "--stress-range is for --control stress or mixture-stress"),
    (["flow-curve", "--rate-range", "1", "10"], "--rate-range is for --control rate"),
])
def test_rheometer_options_refused_not_ignored(argv, words, tmp_path, monkeypatch, capsys):
    """A repeated fraction (its curves repeated) and a range of the other control (ignored)."""
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("argv, words", [
    # the stress factor 1/(2 pi R_i^2 L) divided by zero after the run: exit 1, a traceback word;
    # now every length is held to the physical [1e-6, 10] m with its reason
    (["flow-curve", "--geometry", "couette", "--bob-radius", "1e-300", "--points", "5"],
     "--bob-radius = 1e-300 is outside the valid range [1e-06, 10] m (the narrowest micro-gap"),
    (["flow-curve", "--geometry", "parallel-plate", "--radius", "1e-300", "--points", "5"],
     "--radius = 1e-300 is outside the valid range [1e-06, 10] m (the narrowest micro-gap"),
    (["flow-curve", "--geometry", "couette", "--cup-radius", "1e-300", "--points", "5"],
     "--cup-radius = 1e-300 is outside the valid range [0.013331, 10] m (the cup radius exceeds "
     "the bob radius by a gap of at least 1e-06 m"),
    # named as the option, with the range its own check and the bob's leave, and the reason
    (["flow-curve", "--geometry", "couette", "--cup-radius", "0.005", "--points", "5"],
     "--cup-radius = 0.005 is outside the valid range [0.013331, 10] m (the cup radius exceeds "
     "the bob radius by a gap of at least 1e-06 m"),
    (["flow-curve", "--geometry", "cone-plate", "--cone-angle", "1e-300", "--points", "5"],
     "--cone-angle = 1e-300 is outside the valid range (0.00229183, 10] deg (the gap at the "
     "rim, R tan(angle), at least 1e-06 m"),
    (["material-point", "--control", "volume", "--pressure", "2", "--t-end", "0.01"],
     "--pressure is the imposed pressure of --control pressure"),
    (["material-point", "--stress0", "1", "--pressure0", "2", "--t-end", "0.01"],
     "give --stress0 (start from the steady state at that stress) or --pressure0"),
])
def test_rheometer_geometry_and_control_refusals(argv, words, tmp_path, monkeypatch, capsys):
    """A dimension whose conversion factor is not finite is refused before the run, named as
    the option with its valid range at the other dimensions; options another choice makes
    irrelevant are refused, not ignored."""
    from rheometer.cli import main

    monkeypatch.chdir(tmp_path)
    try:                              # argparse's refusal exits, a later one returns the status
        rc = main(argv)
    except SystemExit as exc:
        rc = exc.code
    assert rc == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0], err
    assert not any(tmp_path.iterdir())
