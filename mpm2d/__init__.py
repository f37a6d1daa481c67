"""mpm2d: a compact, verified two-phase material point method (plane strain and axisymmetric).

Explicit MPM on quadratic B-splines with APIC transfers (FLIP/PIC blends for comparison), update
stress last; granular and fluid points on one grid with implicit nodal drag and buoyancy
(Table 8 of Baumgarten & Kamrin), or a locked mixture; linear elastic, Newtonian fluid and the
Table 8 suspension law (through :mod:`rheology.local_update`); rigid bodies at prescribed
velocity or free under gravity; mirror/periodic/axis boundaries. Kernels in numba.

Modules: :mod:`~mpm2d.shape` (B-splines), :mod:`~mpm2d.grid` (grid, boundaries),
:mod:`~mpm2d.transfer` (P2G/G2P), :mod:`~mpm2d.grid_update` (nodal velocities, drag, buoyancy),
:mod:`~mpm2d.materials`, :mod:`~mpm2d.bodies`, :mod:`~mpm2d.particles`,
:mod:`~mpm2d.simulation` (the step), :mod:`~mpm2d.run` (history, snapshots, checkpoints),
:mod:`~mpm2d.output` (npz, VTK), :mod:`~mpm2d.analytic` (exact solutions),
:mod:`~mpm2d.scenes` (setups), :mod:`~mpm2d.cli`.
"""

from .bodies import RigidBody, box, disk, fill
from .grid import Grid
from .materials import LinearElastic, NewtonianFluid, Suspension
from .particles import ParticleSet
from .run import Scene, run_scene
from .simulation import Drag, Simulation

__all__ = ["Grid", "ParticleSet", "LinearElastic", "NewtonianFluid", "Suspension", "RigidBody",
           "Simulation", "Drag", "Scene", "run_scene", "box", "disk", "fill"]
