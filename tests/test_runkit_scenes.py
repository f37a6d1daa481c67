"""mpm2d's scene declarations are runkit.params schemas: every scene's schema admits its
defaults, and over every number of every scene (at the edges of its range at the defaults,
derived bounds included, and beyond) a value is accepted exactly when it lies inside the range
the schema states, and refused in one line naming it."""

from __future__ import annotations

import math
import re

import pytest

from mpm2d.scenes import SCENES, get_spec
from runkit.params import Schema


def _probes(p, defaults):
    lo, _, _, hi, _, _ = p.bounds(defaults)
    xs = [-1.0, 1e-300, 1.0, 1e300, float("nan")]
    for b in (lo, hi):
        if b is not None and math.isfinite(b):
            xs += [b, math.nextafter(b, -math.inf), math.nextafter(b, math.inf)]
    return xs


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


def _inside(x, text):
    """Whether ``x`` lies in the interval ``text`` opens with ("[a, b)" ...)."""
    m = re.match(r"([\[(])(-inf|[-0-9.e+]+), (inf|[-0-9.e+]+)([\])])", text)
    lo, hi = float(m.group(2)), float(m.group(3))
    if any(math.isclose(x, b, rel_tol=1e-5) for b in (lo, hi)):   # at an edge printed to 6
        return False                                               # digits: either side
    return ((x > lo or (m.group(1) == "[" and x == lo))
            and (x < hi or (m.group(4) == "]" and x == hi)))


@pytest.mark.parametrize("scene", list(SCENES))
def test_every_number_of_every_scene_is_refused_by_its_stated_range(scene, cached_materials):
    spec = get_spec(scene)
    assert isinstance(spec, Schema) and spec.name == scene
    full = spec.check({})                                 # the defaults are valid
    assert set(full) == set(spec.defaults)
    compared = 0
    for k, p in spec.params.items():
        if not p.numeric or spec.defaults[k] is None:
            continue
        for x in _probes(p, spec.defaults):
            try:
                spec.coerce({k: x})
                continue
            except ValueError as exc:
                text = str(exc)
            if "needs about" in text:                     # the memory estimate: not compared
                continue
            assert "\n" not in text and k in text, (scene, k, x, text)
            if text.startswith(f"{k} = ") and "outside the valid range" in text:
                rng = text.split("outside the valid range ")[1]
                assert not _inside(x, rng), (scene, k, x, text)
            compared += 1
    assert compared > 0
