"""Scenes: each a module with ``setup(**params) -> Scene`` whose docstring states the equations,
the parameters (with units) and the command that runs it.

``mpm2d list`` shows them; ``mpm2d run NAME --set key=value --out DIR`` runs one.
"""

from __future__ import annotations

import importlib
import inspect

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
    "wheel": "elastic wheel driven at a prescribed angular velocity (suspension bed)",
}


def get_setup(name: str):
    """The ``setup`` function of scene ``name`` (ValueError if unknown)."""
    key = str(name).strip().lower()
    if key not in SCENES:
        raise ValueError(f"unknown scene {name!r}; valid: {', '.join(SCENES)}")
    return importlib.import_module(f"mpm2d.scenes.{key}").setup


def parameters(name: str) -> dict:
    """Default parameters of a scene."""
    sig = inspect.signature(get_setup(name))
    return {k: p.default for k, p in sig.parameters.items()}
