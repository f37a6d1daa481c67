"""runkit.params and runkit.limits: one check, one refusal with the valid range at the other
values and the reason of the bound, the argparse options, the array check."""

from __future__ import annotations

import argparse
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from runkit import limits as L
from runkit.params import Option, Param, Schema, check_range, valid_interval

D = 5.85e-6                                     # grain diameter [m] (Table 4)


def annulus() -> Schema:
    """A wide-gap Couette cell: the cup beyond the bob by ``cells`` grains at least."""
    def r_min(p):
        return p["r_inner"] + p["cells"] * p["d"]

    return Schema({
        "r_inner": Param(L.ge(10 * D, "a bob of at least ten grains is a continuum wall"),
                         L.LENGTH_MAX, unit="m", doc="bob radius"),
        "r_outer": Param(L.ge(r_min, "each cell of the gap must hold a grain"), L.LENGTH_MAX,
                         unit="m", doc="cup radius"),
        "cells": Param(4, 20000, kind="integer", doc="cells across the gap"),
        "d": Param(L.GRAIN_MIN, L.GRAIN_MAX, unit="m"),
        "mode": Param(kind="choice", choices=("locked", "two-phase")),
        "quiet": Param(kind="bool"),
    }, dict(r_inner=0.0125, r_outer=0.036, cells=200, d=D, mode="locked", quiet=False),
        label=lambda k: "--" + k.replace("_", "-"))


def test_a_static_refusal_names_the_value_the_range_and_the_physical_reason():
    s = annulus()
    with pytest.raises(ValueError) as e:
        s.check({"d": "1.22e-155"})
    assert str(e.value) == ("--d = 1.22e-155 is outside the valid range [1e-08, 0.01] m (a grain "
                            "must be many liquid molecules (~0.3 nm) across for the liquid "
                            "around it to be a continuum)")
    for bad, words in [("nan", "--cells = nan: must be finite"), ("3.5", "is not an integer"),
                       ("x", "--cells = 'x' is not an integer"), ("1e5", r"outside the valid "
                                                                         r"range \[4, 20000\]$")]:
        with pytest.raises(ValueError, match=words):
            s.check({"cells": bad})
    with pytest.raises(ValueError, match="subnormal"):
        s.check({"r_inner": 1e-310})
    with pytest.raises(ValueError, match="--mode = 'x' is not one of locked, two-phase"):
        s.check({"mode": "x"})
    with pytest.raises(ValueError, match="unknown parameter 'gap'"):
        s.check({"gap": 1})


def test_a_derived_refusal_is_said_about_the_given_value_with_its_range_at_the_others():
    """r_outer >= r_inner + cells d: the range printed is exact to its 6 digits."""
    s = annulus()
    with pytest.raises(ValueError) as e:
        s.check({"r_outer": 0.0126})
    lo = 0.0125 + 200 * D                # a closed edge where its 6 digits are valid, else open
    edge = "[" if float(f"{lo:g}") >= lo else "("
    assert str(e.value) == (f"--r-outer = 0.0126 is outside the valid range {edge}{lo:g}, 10] m "
                            "(each cell of the gap must hold a grain)")
    # the bob is named when it is the value given: its range at the default cup and cells
    with pytest.raises(ValueError) as e:
        s.check({"r_inner": 0.0359})
    hi = 0.036 - 200 * D
    assert f"--r-inner = 0.0359 is outside the valid range [5.85e-05, {hi:g}] m" in str(e.value)
    assert "--r-outer: each cell of the gap must hold a grain" in str(e.value)
    # an integer: the integers inside, at the given radii
    with pytest.raises(ValueError) as e:
        s.check({"cells": 300, "r_inner": 0.01, "r_outer": 0.0115})
    top = math.floor(0.0015 / D)
    assert f"valid range [4, {top}]" in str(e.value) and "--cells = 300" in str(e.value)
    # a valid set passes through with canonical types
    out = s.check({"cells": "100", "mode": "TWO-PHASE", "quiet": "yes"})
    assert out["cells"] == 100 and isinstance(out["cells"], int)
    assert out["mode"] == "two-phase" and out["quiet"] is True


def test_no_single_value_can_be_moved_the_refusal_names_them_all():
    s = Schema({"a": Param(0, 10), "b": Param(0, 10),
                "c": Param(L.ge(lambda p: p["a"] + p["b"], "c >= a + b"), 10)},
               dict(a=1, b=1, c=5))
    with pytest.raises(ValueError) as e:       # a = 10 and b = 10 ask c >= 20: nothing fits c
        s.check({"a": 10, "b": 10})
    assert str(e.value) == "with a = 10, b = 10, no value of c is valid (c >= a + b); change a, b"
    with pytest.raises(ValueError) as e:       # a alone can: its range at b = 1, c = 5
        s.check({"a": 8})
    assert str(e.value) == "a = 8 is outside the valid range [0, 4] (c: c >= a + b)"


@settings(max_examples=60, deadline=None)
@given(lo=st.floats(-1e6, 1e6), width=st.floats(1e-6, 1e6), closed=st.booleans())
def test_valid_interval_finds_the_edges_of_a_monotone_check(lo, width, closed):
    hi = lo + width

    def ok(x):
        return (x >= lo if closed else x > lo) and x <= hi

    x0 = lo + 0.5 * width
    if not ok(x0) or width < 1e-4 * max(abs(lo), 1.0):   # narrower than the 6 printed digits
        return
    a, a_closed, b, b_closed = valid_interval(ok, x0)
    assert ok(b) == b_closed and abs(b - hi) <= 5e-6 * max(abs(hi), 1e-300)
    assert a is not None and abs(a - lo) <= 5e-6 * max(abs(lo), 1e-300)
    assert ok(a) == a_closed            # a closed edge is valid, an open one is not


def test_options_are_built_and_refuse_in_one_line(capsys):
    s = annulus()
    p = argparse.ArgumentParser(prog="t")
    p.error = lambda msg: (_ for _ in ()).throw(SystemExit(f"t: error: {msg}"))
    s.add_options(p, ["r_inner", "cells", "mode", "quiet"])
    numeric = [a for a in p._actions if isinstance(a.type, Option)]
    assert [a.dest for a in numeric] == ["r_inner", "cells"]
    ns = p.parse_args(["--cells", "64", "--mode", "two-phase", "--quiet"])
    assert (ns.cells, ns.mode, ns.quiet, ns.r_inner) == (64, "two-phase", True, 0.0125)
    with pytest.raises(SystemExit) as e:
        p.parse_args(["--cells", "inf"])
    assert "--cells = inf: must be finite; valid range [4, 20000]" in str(e.value)
    help_ = {a.dest: a.help for a in p._actions}
    assert "[5.85e-05, 10] m" in help_["r_inner"]


@pytest.mark.parametrize("value", ["nan", "inf", "abc", float("nan")])
def test_a_non_number_gets_its_derived_range_from_formulas_that_read_it(value):
    """A derived bound whose formula reads the refused parameter too (a scene's time scales:
    ``ramp_s = ramp t_c``) raised TypeError on the text 'abc' (and gave NaN on 'nan'): the
    refusal of a value that is no finite number fell back to the static range. The bounds are
    evaluated with the others' values, the refused one at its default."""
    def scales(p):
        return {"t_c": p["height"] ** 2, "ramp_s": p["ramp"] * p["height"] ** 2}

    schema = Schema({"height": Param(0.1, 10.0),
                     "ramp": Param(L.ge(lambda p: 0.2 / scales(p)["t_c"], "ten transits"),
                                   10.0)},
                    {"height": 1.0, "ramp": 0.5})
    with pytest.raises(ValueError) as finite:
        schema.check({"ramp": 0.01, "height": 2.0})
    assert "valid range [0.05, 10] (ten transits)" in str(finite.value)
    with pytest.raises(ValueError) as exc:
        schema.check({"ramp": value, "height": 2.0})
    assert "valid range [0.05, 10] (ten transits)" in str(exc.value), exc.value


def test_the_array_check_is_the_same_check():
    arr = check_range("phi", [0.1, 0.2], 0.0, 0.6, lo_closed=False, hi_closed=False)
    assert arr.dtype == float and arr.shape == (2,)
    with pytest.raises(ValueError, match=r"phi = 0.7 is outside the valid range \(0, 0.6\) "
                                         r"\(phi_j of m\)"):
        check_range("phi", np.array([0.1, 0.7, 0.9]), 0.0, 0.6, lo_closed=False,
                    hi_closed=False, note="phi_j of m")
    with pytest.raises(ValueError, match=r"phi = nan: must be finite; valid range \(0, 0.6\)"):
        check_range("phi", [0.1, np.nan], 0.0, 0.6, lo_closed=False, hi_closed=False)
    with pytest.raises(ValueError, match="is not a number"):
        check_range("phi", "abc")


def test_limits_are_physical_and_state_their_reason():
    """Every bound of runkit.limits has a reason, and the ranges are the physical ones: each
    lower limit is below the paper's values (Table 4: G = 3.8e5 Pa, eta0 = 1e-2 Pa s, d =
    5.85 um, rho = 1620 kg/m^3, Earth's gravity), each upper one above."""
    bounds = {k: v for k, v in vars(L).items() if isinstance(v, L.Bound)}
    assert len(bounds) >= 20 and all(b.why for b in bounds.values())
    for lo, hi, x in [("MODULUS", "MODULUS", 3.8e5), ("VISCOSITY", "VISCOSITY", 1e-2),
                      ("GRAIN", "GRAIN", D), ("DENSITY", "DENSITY", 1620.0),
                      ("GRAVITY", "GRAVITY", 9.81), ("TIME", "TIME", 60.0),
                      ("TAU_STAR", "TAU_STAR", 6.0)]:
        assert bounds[f"{lo}_MIN"].value < x < bounds[f"{hi}_MAX"].value
    assert L.clock_floor(0.0) == 1e-12 and L.clock_floor(1e6) == pytest.approx(1e-3)
    assert L.TIME_MIN.value < L.TIME_MAX.value and L.STRESS_MIN.value < L.STRESS_MAX.value


def test_memory_is_checked_against_what_the_machine_has():
    avail = L.available_memory()
    assert avail > 0
    L.check_memory("--cells", 10, 1e3)
    with pytest.raises(ValueError, match=r"--cells = 1e9 needs about .* GB \(estimate\), more "
                                         r"than 50% of the .* GB available"):
        L.check_memory("--cells", "1e9", 0.6 * avail)
    s = Schema({"n": Param(1, 1e12, kind="integer")}, {"n": 1}, size=lambda p: 1e6 * p["n"])
    assert s.check({"n": 10})["n"] == 10
    with pytest.raises(ValueError, match="n = 1000000000000 needs about"):
        s.check({"n": 10 ** 12})


def material_schema(label=lambda k: f"--set {k}"):
    """A prototype of rheology's Material schema (MIGRATION.md): the paper's field checks, the
    physical ranges of runkit.limits for the scales."""
    import dataclasses

    from rheology.materials import FIELD_UNITS, Material

    def unit(k):
        return "" if FIELD_UNITS[k] == "-" else FIELD_UNITS[k]

    nonneg = {k: Param(0.0, None) for k in ("varphi1", "alpha1", "varphi2", "alpha2", "xi_eps",
                                            "K3", "b")}
    params = {
        "phi_j": Param(L.gt(0.0), L.lt(1.0, "a volume fraction")),
        "phi_c": Param(L.gt(0.0), L.lt(lambda p: p["phi_j"], "phi_c must be below phi_j")),
        "a0": Param(L.gt(0.0)),
        "a_inf": Param(L.ge(lambda p: p["a0"], "a_inf >= a0 makes the stress-controlled "
                                               "steady state unique")),
        "mu_c": Param(L.gt(0.0)),
        "mu_2": Param(L.ge(lambda p: p["mu_c"], "mu_2 >= mu_c"), optional=True),
        "tau_star": Param(L.TAU_STAR_MIN, L.TAU_STAR_MAX, unit="Pa"),
        "eta0": Param(L.VISCOSITY_MIN, L.VISCOSITY_MAX, unit="Pa s"),
        "Delta": Param(0.0, 1.0),
        "K4": Param(0.0, L.le(0.0, "only K4 = 0, the value of every scene of the paper, is "
                                   "implemented")),
        "K0": Param(0.0, 1e6, optional=True),
        **{k: Param(L.MODULUS_MIN, L.MODULUS_MAX, unit="Pa", optional=True)
           for k in ("G", "K", "kappa")},
        **{k: Param(L.DENSITY_MIN, L.DENSITY_MAX, unit="kg/m^3", optional=True)
           for k in ("rho_s", "rho_f")},
        "d": Param(L.GRAIN_MIN, L.GRAIN_MAX, unit="m", also=(0.0,)),
        "phi0": Param(L.gt(0.0), L.lt(lambda p: p["phi_j"], "below phi_j"), optional=True),
        **nonneg,
    }
    assert set(params) == set(FIELD_UNITS)
    for k, p in params.items():
        params[k] = dataclasses.replace(p, unit=p.unit or unit(k))
    names = [f.name for f in dataclasses.fields(Material) if f.name in FIELD_UNITS]
    return params, names


def test_a_material_schema_admits_every_set_of_the_paper_and_explains_as_today():
    """Every parameter set passes the physical ranges; a --set refusal names the parameter
    set with the same range as rheometer's bisection on the Material's checks today, and
    moduli that only arithmetic bounded (G = 1e-300 Pa ran) are refused with their reason."""
    import rheology

    params, names = material_schema()
    for name in rheology.material_names():
        m = rheology.get_material(name)
        Schema(params, {k: getattr(m, k) for k in names}).check({})
    m = rheology.get_material("hermes2016")
    s = Schema(params, {k: getattr(m, k) for k in names}, label=lambda k: f"--set {k}")
    with pytest.raises(ValueError) as e:
        s.check({"phi_j": 0.3})
    assert str(e.value).startswith("--set phi_j = 0.3 is outside the valid range (0.436, 1) "
                                   "(--set phi_c: phi_c must be below phi_j)")
    with pytest.raises(ValueError) as e:
        s.check({"a0": 5.0})
    assert str(e.value).startswith("--set a0 = 5 is outside the valid range (0, 0.8]")
    with pytest.raises(ValueError, match=r"--set G = 1e-300 is outside the valid range \[1, "
                                         r"1e\+12\] Pa, or none \(the weakest colloidal gels"):
        s.check({"G": 1e-300})
    assert s.check({"d": 0.0})["d"] == 0.0 and s.check({"G": "none"})["G"] is None


def test_an_entry_point_checks_its_arguments_once():
    """@checked: the call is checked (one refusal naming the parameter), ``raw`` is not."""
    from runkit.params import checked

    calls = []

    @checked(t_end=Param(L.TIME_MIN, L.TIME_MAX, unit="s"),
             dt=Param(L.gt(0.0), L.le(lambda p: p["t_end"], "a step within the run"), unit="s"))
    def run(t_end=1.0, dt=0.1):
        calls.append((t_end, dt))
        return t_end / dt

    assert run(t_end="2") == pytest.approx(20.0) and calls == [(2.0, 0.1)]
    with pytest.raises(ValueError, match=r"dt = 3 is outside the valid range \(0, 1\] s \(a step "
                                         r"within the run\)"):
        run(dt=3.0)
    assert run.raw(t_end=1.0, dt=3.0) == pytest.approx(1 / 3)      # checked already: no check
    with pytest.raises(ValueError, match=r"--t-end = 1e-300 is outside the valid range"):
        Schema(run.schema.params, run.schema.defaults,
               label=lambda k: "--" + k.replace("_", "-")).check({"t_end": 1e-300})
    with pytest.raises(TypeError, match="declared"):
        checked(x=Param())(lambda y=1: y)
