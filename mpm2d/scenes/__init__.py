"""Scenes: each a module with ``setup(**params) -> Scene`` whose docstring states the equations,
the parameters (with units) and the command that runs it.

``mpm2d list`` shows them; ``mpm2d show NAME`` prints a scene's parameters with their valid
ranges; ``mpm2d run NAME --set key=value --out DIR`` runs one. ``NAME`` may also be the path of
a scene file of the user's with the same shape (``mpm2d run path/to/my_scene.py``; a worked
example: ``mpm2d/examples/elastic_column.py``).

Every scene declares the valid range of every ``setup`` parameter through the one mechanism of
:mod:`mpm2d.scenes.spec` (``@spec.parameters_of(...)``): a new scene must too (``get_spec``
refuses a scene without a declaration).
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import sys
from pathlib import Path

from runkit.params import Schema

from .spec import Param, parameters_of, spec_of

#: scene name -> module (imported on demand)
SCENES = {
    "bar": "axial vibration of an elastic bar (verification: frequency, amplitude, order)",
    "disks": "collision of two elastic disks (energy histories, APIC/FLIP/PIC)",
    "cylinder": "axisymmetric radial vibration of a solid cylinder (verification, J1 mode)",
    "couette": "Newtonian startup of plane Couette flow (verification, series solution)",
    "shear": "homogeneous simple shear of the suspension law (locked mixture)",
    "terzaghi": "Terzaghi consolidation with the two-phase formulation (verification)",
    "column": "two-phase settling column of a suspension under gravity",
    "piston": "rigid piston at prescribed velocity into an elastic bar (impact stress rho c V)",
    "rod_drop": "free rigid rod falling onto a suspension bed (axisymmetric, locked mixture)",
    "wheel": "wheel driven at a prescribed angular velocity on a suspension bed (rigid; spokes=elastic)",
    "intruder": "rigid rod driven at constant speed into a suspension bed: jamming fronts (Figs. 6-7)",
    "impact": "free aluminium rod striking a suspension: impact-activated solidification (Figs. 4-5)",
    "annular": "annular shear cell with swirl (axisymmetric, locked mixture): jammed fronts (Fig. 3)",
}


# ---------------------------------------------------------------- lookup
def is_scene_file(name: str) -> bool:
    """Whether ``name`` names a scene file of the user's (``path/to/my_scene.py``), not a
    built-in scene."""
    return str(name).endswith(".py") or os.sep in str(name)


def _scene_file(name: str):
    """The module of the user's scene file ``name`` (imported once per file, under its stem).

    Raises ValueError (bad input: one line) for a missing file, one that cannot be imported,
    one without a declared ``setup`` or whose stem is another module's name."""
    path = Path(name).expanduser().resolve()
    what = (f"a scene is a built-in name, {', '.join(SCENES)}, or the path of a .py file "
            "declaring setup(**params)")
    if not path.exists():
        raise ValueError(f"scene file {name!r} does not exist ({what})")
    if not path.is_file():
        raise ValueError(f"scene file {name!r} is a folder, not a scene file ({what})")
    if path.suffix != ".py":
        raise ValueError(f"scene file {name!r} is not a Python file (.py) ({what})")
    mod = sys.modules.get(path.stem)
    if mod is not None:
        if Path(getattr(mod, "__file__", "") or "").resolve() == path:
            return mod
        raise ValueError(f"scene file {name!r}: its name {path.stem!r} is that of the module "
                         f"{mod.__name__} already imported; rename the file")
    spec_ = importlib.util.spec_from_file_location(path.stem, path)
    mod = importlib.util.module_from_spec(spec_)
    sys.modules[path.stem] = mod
    try:
        spec_.loader.exec_module(mod)
    except Exception as exc:                   # the user's code: any failure is bad input
        del sys.modules[path.stem]
        raise ValueError(f"scene file {name!r} could not be imported: "
                         f"{type(exc).__name__}: {exc}") from None
    if not callable(getattr(mod, "setup", None)) or \
            getattr(mod.setup, "spec", None) is None:
        del sys.modules[path.stem]
        raise ValueError(f"scene file {name!r} has no setup(**params) declared with "
                         "@mpm2d.scenes.spec.parameters_of (see mpm2d/examples/"
                         "elastic_column.py)")
    return mod


def get_setup(name: str):
    """The (validating) ``setup`` function of scene ``name``: a built-in scene's name, or the
    path of a scene file of the user's (:func:`is_scene_file`); ValueError if unknown."""
    if is_scene_file(name):
        return _scene_file(name).setup
    key = str(name).strip().lower()
    if key not in SCENES:
        raise ValueError(f"unknown scene {name!r}; valid: {', '.join(SCENES)}, or the path of "
                         "a scene file (path/to/my_scene.py)")
    return importlib.import_module(f"mpm2d.scenes.{key}").setup


def get_spec(name: str) -> Schema:
    """The declared parameters of scene ``name`` (:func:`mpm2d.scenes.spec.spec_of`)."""
    return spec_of(get_setup(name))


def parameters(name: str) -> dict:
    """Default parameters of a scene."""
    return dict(get_spec(name).defaults)


__all__ = ["SCENES", "Param", "parameters_of", "get_setup", "get_spec",
           "parameters", "is_scene_file"]
