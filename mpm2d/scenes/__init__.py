"""Scenes: each a module with ``setup(**params) -> Scene`` whose docstring states the equations,
the parameters (with units) and the command that runs it.

``mpm2d list`` shows them; ``mpm2d show NAME`` prints a scene's parameters with their valid
ranges; ``mpm2d run NAME --set key=value --out DIR`` runs one.

Every scene declares the valid range of every ``setup`` parameter through the one mechanism of
:mod:`mpm2d.scenes.spec` (``@spec.parameters_of(...)``): a new scene must too (``get_spec``
refuses a scene without a declaration).
"""

from __future__ import annotations

import importlib

from .spec import Param, SceneSpec, parameters_of

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
def get_setup(name: str):
    """The (validating) ``setup`` function of scene ``name`` (ValueError if unknown)."""
    key = str(name).strip().lower()
    if key not in SCENES:
        raise ValueError(f"unknown scene {name!r}; valid: {', '.join(SCENES)}")
    return importlib.import_module(f"mpm2d.scenes.{key}").setup


def get_spec(name: str) -> SceneSpec:
    """The declared parameters of scene ``name``."""
    setup = get_setup(name)
    spec = getattr(setup, "spec", None)
    if spec is None:
        raise TypeError(f"scene {name}: setup has no declared parameters (use "
                        "mpm2d.scenes.spec.parameters_of)")
    return spec


def parameters(name: str) -> dict:
    """Default parameters of a scene."""
    return dict(get_spec(name).defaults)


__all__ = ["SCENES", "Param", "SceneSpec", "parameters_of", "get_setup", "get_spec",
           "parameters"]
