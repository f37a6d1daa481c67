"""The migration of mpm2d's scene declarations onto runkit.params is mechanical: translated
Param by Param, every scene's schema admits its defaults, and over every number of every scene
the two mechanisms accept and refuse the same values with the same range (derived bounds
included, at the defaults)."""

from __future__ import annotations

import math

import pytest

from mpm2d.scenes import SCENES, get_spec
from runkit.limits import Bound
from runkit.params import Param, Schema


def translate(spec) -> Schema:
    """A scene's SceneSpec as a runkit Schema (what MIGRATION.md does to each declaration)."""
    out = {}
    for k, p in spec.params.items():
        def note(params, p=p):
            return p.note_text(params)

        def bound(x, closed, p=p):
            if x is None:
                return None
            return Bound(x, closed, note if p.derived and callable(x) else "")

        if p.kind == "material":
            out[k] = Param(kind="text", doc="material", convert=lambda v, p=p, k=k: p.convert(k, v))
        elif p.kind == "choice":
            out[k] = Param(kind="choice", choices=p.choices, optional=p.optional)
        elif p.kind == "bool":
            out[k] = Param(kind="bool", optional=p.optional)
        else:
            out[k] = Param(bound(p.lo, p.lo_closed), bound(p.hi, p.hi_closed), unit=p.unit,
                           kind="integer" if p.integer else "number", optional=p.optional)
    return Schema(out, spec.defaults, where=f"scene {spec.name}")


def _probes(p, defaults):
    lo, hi = p.lo, p.hi
    lo = lo(defaults) if callable(lo) else lo
    hi = hi(defaults) if callable(hi) else hi
    xs = [-1.0, 1e-300, 1.0, 1e300, float("nan")]
    for b in (lo, hi):
        if b is not None and math.isfinite(b):
            xs += [b, math.nextafter(b, -math.inf), math.nextafter(b, math.inf)]
    return xs


SCENE_NAMES = [pytest.param(n, marks=pytest.mark.xfail(
    strict=True, reason="intruder's optional geometry is filled from its layout (spec.Param.fill), "
                        "which runkit.params.Param does not model yet")) if n == "intruder" else n
               for n in SCENES]


@pytest.fixture
def cached_materials(monkeypatch):
    """A registry set is a frozen Material: the derived bounds' many look-ups share one."""
    import functools

    import rheology
    import rheology.materials as mats

    plain = mats.get_material
    cached = functools.lru_cache(maxsize=None)(lambda name: plain(name))

    def get(name, **overrides):
        return plain(name, **overrides) if overrides or not isinstance(name, str) else cached(name)

    monkeypatch.setattr(mats, "get_material", get)
    monkeypatch.setattr(rheology, "get_material", get)


@pytest.mark.parametrize("scene", SCENE_NAMES)
def test_every_number_of_every_scene_is_refused_alike(scene, cached_materials):
    spec = get_spec(scene)
    schema = translate(spec)
    full = schema.check({})                               # the defaults are valid
    assert set(full) == set(spec.defaults)
    compared = 0
    for k, p in spec.params.items():
        if p.kind != "number" or spec.defaults[k] is None:
            continue
        for x in _probes(p, spec.defaults):
            try:
                spec.coerce({k: x})
                old_ok, old_text = True, ""
            except ValueError as exc:
                old_ok, old_text = False, str(exc)
            try:
                schema.check({k: x})
                new_ok, new_text = True, ""
            except ValueError as exc:
                new_ok, new_text = False, str(exc)
            if "needs about" in old_text + new_text:      # the memory estimate: not compared
                continue
            assert old_ok == new_ok, (scene, k, x, old_text, new_text)
            if old_text.startswith(f"{k} = ") and "outside the valid range" in old_text:
                rng = old_text.split("outside the valid range ")[1]
                rng = rng.split(" (")[0].split(" at the")[0]
                assert rng in new_text, (scene, k, x, old_text, new_text)
            compared += 1
    assert compared > 0
