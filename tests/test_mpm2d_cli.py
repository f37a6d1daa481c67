"""mpm2d command line: every ``--set`` key of every scene refuses bad values (NaN, inf, negative,
zero, huge, out of its declared or material-derived range, wrong type) with exit 2, one line on
stderr naming the key, nothing written; the issue's instances; ``mpm2d show`` prints every
parameter with its valid range; run options through ``Number``; the memory estimate."""

from __future__ import annotations

import contextlib
import io
import math
import re
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mpm2d.cli import main
from mpm2d.scenes import SCENES, get_spec

KEYS = [(scene, key) for scene in SCENES for key in get_spec(scene).params]


def _call(argv):
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            rc = main(argv)
        except SystemExit as exc:                  # argparse's usage errors (Number types)
            rc = exc.code
    return rc, err.getvalue().strip().splitlines()


class _P:
    """A scene parameter as these tests read it: kind number (integer or not), material
    (text), choice or bool; its bounds' closedness at the defaults."""

    def __init__(self, p, defaults):
        self.param, self.optional, self.options, self.also = p, p.optional, p.options, p.also
        self.kind = {"integer": "number", "text": "material"}.get(p.kind, p.kind)
        self.integer = p.kind == "integer"
        b = p.bounds(defaults) if p.numeric else (None, True, "", None, True, "")
        self.lo, self.lo_closed, _, self.hi, self.hi_closed, _ = b


def _bounds(scene, key):
    spec = get_spec(scene)
    p = _P(spec.params[key], spec.defaults)
    return p, p.lo, p.hi


def _fmt(x) -> str:
    return repr(x) if isinstance(x, float) else str(x)


@st.composite
def bad_value(draw, scene, key):
    """A value outside the declared valid set of ``scene.key`` (others at their defaults)."""
    p, lo, hi = _bounds(scene, key)
    if p.kind == "material":                      # neither a set name nor a readable file
        from rheology import material_names

        names = {n.lower() for n in material_names()}
        return draw(st.one_of(st.sampled_from(["nan", "inf", "-1", "singh2018_a", "x.json",
                                               "/nonexistent/m.json"]),
                              st.text(alphabet="abcdefghijklmnopqrstuvwxyz_0123456789.-",
                                      min_size=1, max_size=12)).filter(
            lambda s: s.lower() not in names - {"singh2018_a"}))
    if p.kind == "choice":
        opts = {str(o).lower() for o in p.options()}
        return draw(st.text(alphabet="abcdefghijklmnopqrstuvwxyz_0123456789.-", min_size=1,
                            max_size=12).filter(lambda s: s.lower() not in opts
                                                and s.lower() != "none"))
    if p.kind == "bool":
        return draw(st.sampled_from(["maybe", "2", "-1", "nan", "tru"]))
    cands = ["nan", "inf", "-inf", "NaN", "1e999", "abc", "1,5", "0x", "[]"]
    cands += ["1e300", "-1e300"]                   # huge: every range is finite (see below)
    if lo is not None:
        cands += [_fmt(lo - max(1.0, abs(lo))), _fmt(-abs(lo) - 1.0)]
        if not p.lo_closed:
            cands.append(_fmt(lo))                 # e.g. zero for a positive parameter
        elif lo != 0:
            cands.append(_fmt(lo * (1 - 1e-6) if lo > 0 else lo * (1 + 1e-6)))
    if hi is not None:
        cands += [_fmt(hi + max(1.0, abs(hi))), _fmt(hi * 10 + 1)]
        if not p.hi_closed:
            cands.append(_fmt(hi))
    if p.integer:
        cands += [_fmt((lo or 0) + 0.5), "2.5", "true"]
    return draw(st.sampled_from(cands))


def _is_bad(scene, key, text) -> bool:
    """Independent judgement: is ``text`` outside ``scene.key``'s valid set?"""
    p, lo, hi = _bounds(scene, key)
    if p.kind != "number":
        return True                                # drawn outside the choices by construction
    try:
        x = float(text)
    except ValueError:
        return True
    if not math.isfinite(x) or (p.integer and x != int(x)):
        return True
    if x in p.also:                                # a value valid besides the range (0: none)
        return False
    if lo is not None and (x < lo or (x == lo and not p.lo_closed)):
        return True
    return hi is not None and (x > hi or (x == hi and not p.hi_closed))


@pytest.mark.parametrize("scene, key", KEYS, ids=[f"{s}.{k}" for s, k in KEYS])
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_every_set_key_refuses_bad_values(scene, key, data):
    value = data.draw(bad_value(scene, key), label="value")
    assert _is_bad(scene, key, value)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        rc, err = _call(["run", scene, "--set", f"{key}={value}", "--out", str(out), "--quiet",
                         "--no-vtk"])
        assert rc == 2, (value, err)
        assert len(err) == 1 and err[0].startswith("mpm2d run: error: "), err
        assert f"{key} = " in err[0], err
        assert any(w in err[0] for w in ("range", "one of", "true or false")), err
        assert not out.exists()


@pytest.mark.parametrize("scene, key", KEYS, ids=[f"{s}.{k}" for s, k in KEYS])
def test_every_number_has_a_finite_range_and_the_default_inside(scene, key):
    """'huge' is bad for every key (a finite upper bound), and every default is valid."""
    p, lo, hi = _bounds(scene, key)
    default = get_spec(scene).defaults[key]
    if p.kind == "number":
        assert lo is not None and hi is not None and math.isfinite(lo) and math.isfinite(hi)
        assert default is None and p.optional or not _is_bad(scene, key, str(default))
    elif p.kind == "material":
        from rheology import material_names

        assert str(default) in material_names()
    else:
        assert str(default).lower() in {str(o).lower() for o in
                                        (p.options() if p.kind == "choice" else (True, False))}


@pytest.mark.parametrize("argv, words", [
    (["run", "column", "--set", "phi0=0.7"], "phi0 = 0.7 is outside the valid range [1e-06, 0.535) "
                                             "(phi_j of material 'rod_impact')"),
    (["run", "column", "--set", "t_end=-1"], "t_end = -1 is outside the valid range [1e-12, 1e+09] s"),
    (["run", "column", "--set", "t_end=0"], "t_end = 0 is outside the valid range"),
    (["run", "column", "--set", "cells=0"], "cells = 0 is outside the valid range [2, 100000]"),
    (["run", "column", "--set", "ppc=0"], "ppc = 0 is outside the valid range [1, 8]"),
    (["run", "column", "--set", "t_end=nan"], "t_end = nan: must be finite"),
    (["run", "bar", "--set", "periods=nan"], "periods = nan: must be finite"),
    (["run", "column", "--set", "gravity=inf"], "gravity = inf: must be finite"),
    (["run", "shear", "--set", "phi=0.6"], "phi_j of material 'annular_shear'"),
    (["run", "shear", "--set", "material=singh2018_a"], "material = 'singh2018_a' is not one of"),
    (["run", "bar", "--set", "cellz=4"], "unknown parameter 'cellz' of scene bar"),
    (["run", "bar", "--set", "cells=4.5"], "cells = 4.5 is not an integer"),
    (["run", "bar", "--set", "transfer=mls"], "transfer = 'mls' is not one of apic, flip, pic"),
    (["run", "wheel", "--set", "radius=5"], "radius = 5 is outside the valid range [0.0766667, "
                                            "0.155455) m at the other parameters' values"),
    (["run", "disks", "--set", "cells=4096", "--set", "ppc=8"], "needs about"),
    (["run", "bar", "--frames", "-1"], "--frames = -1 is outside the valid range"),
    (["run", "bar", "--frames", "0"], "--frames = 0 is outside the valid range"),
    (["run", "bar", "--checkpoint-every", "-1"], "--checkpoint-every = -1 is outside"),
    (["run", "bar", "--checkpoint-every", "nan"], "--checkpoint-every = nan: must be finite"),
    (["run", "bar", "--threads", "0"], "--threads = 0 is outside the valid range"),
    (["run", "bar", "--threads", "100000"], "--threads = 100000 is outside the valid range"),
    (["run", "bar", "--resume"], "no checkpoint"),
])
def test_issue_instances_are_refused_by_name(argv, words, tmp_path):
    out = tmp_path / "o"
    rc, err = _call(argv + ["--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1 and words in err[0], err
    assert not out.exists()


def test_show_prints_every_parameter_with_its_range():
    for scene in SCENES:
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            assert main(["show", scene]) == 0
        text = out.getvalue()
        spec = get_spec(scene)
        for key in spec.params:
            line = next(ln for ln in text.splitlines() if ln.startswith(f"  {key} = "))
            assert "valid: " in line, line
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        main(["show", "column"])
    assert "phi0 = 0.3  (initial solid volume fraction; valid: [1e-06, 0.535) (phi_j of material " \
           "'rod_impact'))" in out.getvalue()
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        main(["show", "shear"])
    assert "override as material_<field>" not in out.getvalue()


def test_python_api_validates_too():
    from mpm2d.scenes import bar, column

    with pytest.raises(ValueError, match=r"phi0 = 0.6 is outside the valid range \[1e-06, 0.535\)"):
        column.setup(phi0=0.6)
    with pytest.raises(ValueError, match="cells = True is not an integer"):
        bar.setup(cells=True)
    with pytest.raises(ValueError, match="unknown parameter 'lenght'"):
        bar.setup(lenght=2.0)


def test_mass_fraction_sets_the_scene_volume_fraction(tmp_path, capsys):
    """--mass-fraction gives the scene's phi by Eq. (20) with its material's densities; a scene
    without a suspension fraction, or a fraction given twice, is refused."""
    import json

    from rheology.sample import Densities, volume_fraction

    out = tmp_path / "mf"
    assert main(["run", "shear", "--mass-fraction", "0.42", "--set", "t_end=0.001", "--quiet",
                 "--no-vtk", "--out", str(out)]) == 0
    phi = float(volume_fraction(0.42, Densities(grain=1620.0, liquid=1620.0)))  # annular_shear
    assert json.loads((out / "manifest.json").read_text())["params"]["phi"] == pytest.approx(phi)
    assert f"phi = {phi:.5g}" in capsys.readouterr().out
    for argv, word in ((["run", "bar", "--mass-fraction", "0.4"], "no suspension volume fraction"),
                       (["run", "shear", "--mass-fraction", "0.4", "--set", "phi=0.4"],
                        "not both")):
        assert main(argv + ["--out", str(tmp_path / "x")]) == 2
        assert word in capsys.readouterr().err and not (tmp_path / "x").exists()


def test_bad_value_of_a_derived_bound_states_the_derived_range(capsys, tmp_path):
    """phi0 = nan names phi_j of the scene's material as the bound, not the static (0, inf)."""
    assert main(["run", "column", "--set", "phi0=nan", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err
    assert "valid range [1e-06, 0.535) (phi_j of material 'rod_impact')" in err and "inf)" not in err


@pytest.mark.parametrize("scene, key, finite, rng", [
    ("terzaghi", "ramp", "0.01", "[0.0484909, 10]"),
    ("bar", "v0", "1e-9", "[3.16228e-08, 0.316228"),
])
@pytest.mark.parametrize("value", ["nan", "inf", "-inf", "abc"])
def test_a_non_number_states_the_derived_range_of_a_finite_refusal(scene, key, finite, rng, value,
                                                                   tmp_path):
    """terzaghi ramp = nan printed the static 'valid range [0, 10]' where ramp = 0.01 printed
    the derived [0.0484909, 10]: the derived bound's formula (the scene's time scales) read the
    refused text itself. A value that is no finite number states the derived range too."""
    out = tmp_path / "x"
    rc, err = _call(["run", scene, "--set", f"{key}={finite}", "--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1 and f"valid range {rng}" in err[0], err
    rc, err = _call(["run", scene, "--set", f"{key}={value}", "--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith(f"mpm2d run: error: {key} = ") and f"valid range {rng}" in err[0], err
    assert not out.exists()


@pytest.mark.parametrize("argv", [["run", "bar"], ["sweep", "bar", "--set", "cells=4,8"]])
def test_empty_out_is_refused(argv, tmp_path, monkeypatch, capsys):
    """--out '' ran the scene into its default folder (mpm2d) or the current one (shear1d):
    refused by runkit.io.check_output_dir, one line, exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    assert main(argv + ["--out", ""]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--out = '' is empty" in err[0], err
    assert not any(tmp_path.iterdir())


# ---------------------------------------------------------------- fresh-user findings (batch 2)
def _ranges(text):
    """Every numeric '[a, b]'-style range printed in ``text`` as (lo, hi)."""
    import re

    out = []
    for lo, hi in re.findall(r"[\[(](-?[0-9.e+-]+|-inf), (-?[0-9.e+-]+|inf)[\])]", text):
        out.append((float(lo), float(hi)))
    return out


@pytest.mark.parametrize("argv, words", [
    # radius = 1e-300 was refused as the default hub_radius with the range [0.0133, -0.0267]
    # (1e-300 is now below the physical LENGTH_MIN: 0.01 m is inside it)
    (["run", "wheel", "--set", "radius=0.01"],
     "radius = 0.01 is outside the valid range [0.0766667, 0.155455) m at the other "
     "parameters' values (hub_radius = 0.05 must be within one cell to the radius - 2 cells)"),
    # E = 5 Pa (inside its physical range [1, 1e12] Pa) with the default v0: 1% strain,
    # v0 <= 0.01 sqrt(E/rho), so E >= 10 Pa
    (["run", "bar", "--set", "E=5"], "E = 5 is outside the valid range [10, 1e+12] Pa"),
    # cells_per_mm = 0.1 left the default depth below 4 cells: 4e-3/cpm <= 0.035 -> 0.114..;
    # the rod radius (one cell) and the bed radius (rod + 4 cells) bound it more
    (["run", "intruder", "--set", "cells_per_mm=0.1"], "cells_per_mm = 0.1 is outside the valid "
                                                       "range [0.314961, 20] 1/mm"),
    # an own derived bound with a physical lower end (TIME_MIN): not the smallest normal float
    (["run", "intruder", "--set", "t_end=10"], "t_end = 10 is outside the valid range [1e-12, 0.16] s"),
])
def test_cross_parameter_refusal_names_the_parameter_set(argv, words, tmp_path):
    """A value inside its own declared range that makes another parameter's derived range
    empty is refused as the parameter the user set, with its valid range at the others' values;
    no printed range is inverted."""
    out = tmp_path / "o"
    rc, err = _call(argv + ["--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1 and words in err[0], err
    assert all(lo <= hi for lo, hi in _ranges(err[0])), err
    assert not out.exists()


def test_valid_range_is_the_interval_of_the_checks():
    """Schema.valid_range of a scene declaration: the bisection finds the bounds of a synthetic
    declaration exactly (to the 6 digits printed), open or closed as declared; an empty derived
    range is never printed and the message says which given parameter to change."""
    from mpm2d.scenes.spec import Param, parameters_of

    @parameters_of(x=Param(0.0, 1.0, lo_closed=False),
                   y=Param(lambda p: p["x"], lambda p: p["z"] - p["x"], note="x to z - x"),
                   z=Param(0.0, 2.0), mode=Param(choices=("a", "b")),
                   w=Param(lambda p: 0.0 if p["mode"] == "a" else 1.0,
                           lambda p: 1.0 if p["mode"] == "a" else 0.0))
    def toy(x=0.1, y=0.3, z=2.0, mode="a", w=0.5):
        return None

    spec = toy.spec
    full = {"x": 0.8, "y": 0.3, "z": 2.0, "mode": "a", "w": 0.5}
    rng = spec.valid_range("x", full)          # y >= x -> x <= 0.3; y <= z - x -> x <= 1.7
    assert rng == (0.0, False, 0.3, True)
    with pytest.raises(ValueError) as exc:
        spec.coerce({"x": 0.8})
    assert str(exc.value).startswith("x = 0.8 is outside the valid range (0, 0.3] at the other "
                                     "parameters' values (y = 0.3 must be within x to z - x)")
    with pytest.raises(ValueError) as exc:
        spec.coerce({"mode": "b"})               # w in [1, 0]: no number given to blame
    text = str(exc.value)
    assert "with mode = b, no value of w is valid" in text and "change mode" in text
    assert "[1, 0]" not in text


def test_run_quiet_prints_nothing(tmp_path, capsys):
    """--quiet: no 'setting up scene' line, no description, no closing line (stdout and stderr
    empty on success), the run's files written; a run inside a quiet run is quiet too (the
    wheel report's sub-runs pass their own log=print)."""
    out = tmp_path / "q"
    assert main(["run", "bar", "--set", "cells=8", "--set", "ppc=1", "--set", "periods=0.05",
                 "--no-vtk", "--quiet", "--out", str(out)]) == 0
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err == "", cap
    assert (out / "history.csv").is_file() and (out / "manifest.json").is_file()

    from mpm2d.run import _Quiet, run_scene
    from mpm2d.scenes import get_setup

    with _Quiet(True):
        run_scene(get_setup("bar"), tmp_path / "inner", {"cells": 8, "ppc": 1, "periods": 0.05},
                  vtk=False, log=print, progress=True)
    cap = capsys.readouterr()
    assert cap.out == "" and cap.err == "", cap
    assert main(["run", "bar", "--set", "cells=8", "--set", "ppc=1", "--set", "periods=0.05",
                 "--no-vtk", "--out", str(tmp_path / "loud")]) == 0
    loud = capsys.readouterr().out                # the default still talks (the set-up line
    assert "finished at t = " in loud and "setting up" not in loud   # only for a slow set-up)


def test_step_count_is_refused_before_the_set_up(tmp_path):
    """intruder --set cfl=1e-300 was refused only after its 12-17 s set-up. cfl's range is now
    the stated limit [0.01, 1] (stability; no accuracy below), and a run needing more than
    MAX_STEPS steps is refused before the set-up: the scene states its first stable step from
    its parameters (``steps``), the refusal names the given value with its bound at the
    others, exit 2, nothing written."""
    from mpm2d.run import MAX_STEPS, run_scene
    from mpm2d.scenes import get_setup

    real = get_setup("wheel")

    def setup(**params):
        raise AssertionError("the set-up ran")

    setup.spec = real.spec
    out = tmp_path / "o"
    with pytest.raises(ValueError) as exc:
        run_scene(setup, out, {"cfl": "1e-300"}, log=lambda m: None, scene_name="wheel")
    assert str(exc.value).startswith("cfl = 1e-300 is outside the valid range [0.01, 1] (a step "
                                     "below 1% of the stable one gains no accuracy")
    with pytest.raises(ValueError) as exc:
        run_scene(setup, out, {"omega": "1e-4", "t_end": "1e5"}, log=lambda m: None,
                  scene_name="wheel")
    text = str(exc.value)
    assert text.startswith("scene wheel: t_end = 100000 makes the run too long (a step of ")
    assert "more than 1e+08); valid: t_end <= " in text
    dt = real.spec.steps({**real.spec.defaults, "omega": 1e-4})[0]
    hi = float(re.search(r"valid: t_end <= (\S+) s at the other values", text).group(1))
    assert hi == pytest.approx(MAX_STEPS * dt, rel=1e-2) and hi <= MAX_STEPS * dt
    assert not out.exists()
    # the CLI: one line, exit 2
    rc, err = _call(["run", "wheel", "--set", "cfl=1e-300", "--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1 and "cfl = 1e-300 is outside the valid range [0.01, 1] (" \
        in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_step_bound_is_above_the_stable_step():
    """The pre-set-up bound is an upper bound of the set-up's first stable step (so the early
    refusal never refuses a run the later check would accept): intruder at its defaults."""
    from mpm2d.scenes import get_setup, get_spec
    from mpm2d.scenes.spec import step_bound

    spec = get_spec("intruder")
    params = spec.validate({})
    dt_max, t_end, _ = step_bound(spec, params)
    sim = get_setup("intruder")(**params).sim
    assert sim.stable_dt() <= dt_max and t_end == params["t_end"]


def test_set_up_warnings_are_not_printed_before_the_refusal(tmp_path):
    """column kappa = 1e-300: numpy's 'overflow encountered in exp' was printed before the
    refusal; the refusal (by kappa's physical range, before the set-up) is the only line."""
    import warnings

    out = tmp_path / "o"
    with warnings.catch_warnings():
        warnings.simplefilter("error")           # a warning that escaped would fail the run
        rc, err = _call(["run", "column", "--set", "kappa=1e-300", "--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1, err
    assert "kappa = 1e-300 is outside the valid range [1, 1e+12] Pa (" in err[0]
    assert not out.exists()


def test_run_takes_one_mass_fraction_and_says_leftovers_as_run(tmp_path):
    """'mpm2d run column --mass-fraction 0.5 0.6' said 'mpm2d: error: unrecognized arguments:
    0.6' while the help said 'mass fraction(s)': several values are refused by mpm2d run with
    what to do, a leftover argument is said by 'mpm2d run:', nothing written."""
    out = tmp_path / "o"
    rc, err = _call(["run", "column", "--mass-fraction", "0.5", "0.6", "--out", str(out)])
    assert rc == 2 and len(err) == 1 and err[0].startswith("mpm2d run: error: --mass-fraction "
                                                           "takes one value per run"), err
    rc, err = _call(["run", "column", "--set", "t_end=0.01", "0.6", "--out", str(out)])
    assert rc == 2 and len(err) == 1, err
    assert err[0].startswith("mpm2d run: error: unrecognized arguments: 0.6")
    assert not out.exists()


def test_column_cells_finer_than_a_grain_are_refused(tmp_path, capsys):
    """A cell of at least one grain diameter (the continuum limit): height >= cells x d. 1 um
    cells for 0.5 mm grains ran with exit 0 and relative_error 0.996."""
    out = tmp_path / "col"
    assert main(["run", "column", "--set", "height=2e-5", "--set", "t_end=1e-4",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "height = 2e-05 is outside the valid range [0.01, 10] m" in err[0]
    assert "grain diameter" in err[0] and not out.exists()


# ---------------------------------------------------------------- physical limits (round 3)
#: dimensional parameters whose tiny values are valid, with the reason
NOT_PHYSICAL_AT_ZERO = {
    ("disks", "offset"): "a signed displacement: 1e-300 m is a head-on collision",
    ("intruder", "fit_margin"): "0 (fitted to the floor) is valid",
    ("wheel", "start_angle"): "an angle from the vertical: 0 is valid",
}
DIMENSIONAL = [(scene, key) for scene, key in KEYS if get_spec(scene).params[key].numeric
               and get_spec(scene).params[key].unit
               and (scene, key) not in NOT_PHYSICAL_AT_ZERO]


def _has_reason(line: str) -> bool:
    """A refusal's text after its range holds a parenthesised reason."""
    m = re.search(r"is outside the valid range \S+, \S+(.*)$", line)
    return m is not None and re.search(r"\(\s*[^\s)]", m.group(1)) is not None


@pytest.mark.parametrize("value", ["1e-300", "1e300"])
@pytest.mark.parametrize("scene, key", DIMENSIONAL)
def test_every_dimensional_parameter_has_its_physical_limits(scene, key, value, tmp_path):
    """Every scene parameter with a unit has the physical limits of runkit.limits (or tighter,
    from the other parameters) as its bounds: 1e-300 and 1e300 are refused before the set-up
    with exit 2, one line naming the parameter, its range and the reason, nothing written
    (shear rate=1e-300 ran to 5.75e+279 relative differences; impact and intruder v0=1e-300
    ran for minutes; shear height=1e-300 broke the set-up)."""
    out = tmp_path / "o"
    rc, err = _call(["run", scene, "--set", f"{key}={value}", "--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1, err
    assert re.search(rf"\b{key} = 1e[-+]?300 is outside the valid range", err[0]), err
    assert _has_reason(err[0]), err
    assert not out.exists()


@pytest.mark.parametrize("scene, key", [k for k in KEYS if get_spec(k[0]).params[k[1]].numeric])
def test_every_bound_has_a_reason(scene, key):
    """Every bound of every numeric scene parameter states its reason (cells [2, 100000], nu
    (-1, 0.5), impact v0 (0, 5] and shear p0 [0, 1e9] had none; disks radius's only explained
    its lower end)."""
    spec = get_spec(scene)
    p = spec.params[key]
    for b in (p.lo, p.hi):
        assert b is not None, (scene, key)
        assert b.at(dict(spec.defaults))[2], (scene, key, b)


#: every scene's run length: (scene, its parameter, a too-short run, a too-long run: --set
#: values, None where none is possible: piston's run ends before the reflection, at most
#: t_end_fraction cells/cfl <= 1e7 steps)
RUN_LENGTHS = [
    ("bar", "periods", ["periods=1e-6"], ["periods=1000", "cells=100000"]),
    ("disks", "t_end", ["t_end=1e-9"], ["t_end=1e9"]),
    ("cylinder", "periods", ["periods=1e-6"], ["periods=1000", "cells=100000"]),
    ("couette", "t_end_T", ["t_end_T=1e-9"], ["t_end_T=100", "cells=5000"]),
    ("shear", "t_end", ["t_end=1e-9"], ["t_end=1e9"]),
    ("terzaghi", "t_end_T", ["t_end_T=1e-9"], ["t_end_T=100", "cells=100000"]),
    ("column", "t_end", ["t_end=1e-9"], ["t_end=1e9"]),
    ("piston", "t_end_fraction", ["t_end_fraction=1e-9"], None),
    ("rod_drop", "t_end", ["t_end=1e-9"], ["t_end=1e9"]),
    ("wheel", "t_end", ["omega=1", "t_end=1e-9"], ["omega=1e-4", "t_end=1e5"]),
    ("intruder", "t_end", ["t_end=1e-9"], ["v0=1e-6", "t_end=1000"]),
    ("impact", "t_end", ["t_end=1e-9"], ["t_end=1e9"]),
    ("annular", "rotation", ["rotation=1e-8"], ["rotation=100", "cells=4096"]),
]


def test_every_scene_with_a_run_length_is_in_the_table():
    assert {s for s, *_ in RUN_LENGTHS} == set(SCENES)


@pytest.mark.parametrize("scene, key, sets", [
    (scene, key, (short, "short")) for scene, key, short, _ in RUN_LENGTHS] + [
    (scene, key, (long, "long")) for scene, key, _, long in RUN_LENGTHS if long is not None],
    ids=lambda x: x[1] if isinstance(x, tuple) else str(x))
def test_a_step_count_bound_is_stated_in_the_parameters_units(scene, key, sets, tmp_path):
    """disks t_end = 1e-300 was refused as '7.43e-299 steps; valid: 1 to 1e+08 steps'; then
    cylinder periods = 1e-6 (and couette, terzaghi t_end_T, piston t_end_fraction, ...) was
    refused after the set-up as 'an end time of 4.73e-08 s is ... valid: an end time in
    [0.000451, 4.51e+04] s', not the parameter the user set. Every scene states its first
    stable step from its parameters (``steps``): a run too short or too long is refused before
    the set-up, exit 2, one line naming the parameter with its bound in its units at the other
    values, nothing written."""
    sets, which = sets
    out = tmp_path / "o"
    argv = ["run", scene] + [a for kv in sets for a in ("--set", kv)]
    rc, err = _call(argv + ["--out", str(out), "--quiet"])
    assert rc == 2 and len(err) == 1, err
    value = dict(kv.split("=") for kv in sets)[key]
    unit = get_spec(scene).params[key].unit
    m = re.search(rf"scene {scene}: (?:.*; )?{key} = (\S+) makes the run too {which} \(.*\); "
                  rf"valid: {key} ([<>]=) (\S+){' ' + re.escape(unit) if unit else ''} at the "
                  "other values", err[0])
    assert m and float(m.group(1)) == float(value), err
    assert m.group(2) == (">=" if which == "short" else "<="), err
    bound = float(m.group(3))
    assert (bound > float(value)) if which == "short" else (bound < float(value)), err
    assert "an end time of" not in err[0] and "steps;" not in err[0], err
    assert not out.exists()


def test_a_scene_path_that_is_not_a_py_file_says_so(tmp_path):
    """'mpm2d run README.md' said the file does not exist: it exists and is not a .py file."""
    readme = tmp_path / "README.md"
    readme.write_text("a note\n")
    for path, words in ((readme, "is not a Python file (.py)"), (tmp_path, "is a folder"),
                        (tmp_path / "none.py", "does not exist")):
        rc, err = _call(["run", str(path), "--out", str(tmp_path / "o"), "--quiet"])
        assert rc == 2 and len(err) == 1 and words in err[0], err
    assert not (tmp_path / "o").exists()


def test_show_bar_states_v0_without_a_measurement_history(capsys):
    """The v0 range of 'mpm2d show bar' carried '(v0 = 1e-300 fitted omega at the edge of its
    window)' and closed with ']' where the refusal said ')': both state the same range."""
    assert main(["show", "bar"]) == 0
    line = next(l for l in capsys.readouterr().out.splitlines() if l.strip().startswith("v0 ="))
    assert "1e-300" not in line and "strain amplitude" in line
    rc, err = _call(["run", "bar", "--set", "v0=1", "--out", "never", "--quiet"])
    rng = re.search(r"valid range (\S+, \S+ m/s)", err[0]).group(1)
    assert rc == 2 and f"valid: {rng}" in line, (line, err)


def test_a_resumed_run_shows_its_progress_over_the_whole_run(monkeypatch):
    """A resumed intruder said '15.5% t = 0.006337/0.02 s' (32% of the run), a resumed finished
    disks '0.0% t = 3.003/3 s': the percentage counts from the run's start, the time left from
    the pace since the resume."""
    from runkit.run import Progress

    clock = [0.0]
    monkeypatch.setattr("runkit.run.time.perf_counter", lambda: clock[0])
    buf = io.StringIO()
    bar = Progress(1.0, 2.0, 100, t_start=0.0, stream=buf, label="demo", every=30.0)
    for k in range(1, 31):                   # 0.3 s of the run in 30 wall s after the resume
        clock[0] = float(k)
        bar.update(1.0 + 0.01 * k, 100 + k)
    assert buf.getvalue().splitlines()[0] == ("demo:  65.0% t = 1.3/2 s, step 130, 1e+03 "
                                              "ms/step, 0:30 elapsed, ~1:10 left")
    done = io.StringIO()
    Progress(3.003, 3.0, 500, t_start=0.0, stream=done, label="disks").close(3.003, 500)
    assert done.getvalue().startswith("disks: 100.0% t = 3.003/3 s")
