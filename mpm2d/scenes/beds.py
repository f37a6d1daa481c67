"""A scene's suspension bed as material point sets, in the mode the scene runs.

``mode="locked mixture"``: one set ``bed`` of the suspension law with the undrained pore pressure
(grains and fluid move together); ``mode="two-phase"``: the granular set ``bed`` and a Newtonian
``fluid`` set on the same points, coupled by Beetstra drag (Table 8). Which mode a scene needs
follows from its drainage time L^2/c_v (c_v the consolidation coefficient of the jammed skeleton
and the pore fluid) against its duration; each scene's docstring gives the numbers.
"""

from __future__ import annotations

from ..materials import NewtonianFluid, Suspension
from ..particles import ParticleSet
from ..simulation import Drag


def suspension_bed(m, x, area, phi0: float, mode: str, axisymmetric: bool = False):
    """The bed's point sets and the Simulation keywords the mode needs.

    Parameters
    ----------
    m : rheology.Material
        The suspension (two-phase needs d, rho_f and the drag parameters).
    x : (n, 2) array [m], area : (n,) array [m^2]
        Point positions and in-plane areas.
    phi0 : float
        Initial solid volume fraction (f = 0: the structure at rest).
    mode : {"two-phase", anything else = locked mixture}
    axisymmetric : bool

    Returns
    -------
    (list of ParticleSet, dict of Simulation keywords: ``drag`` in two-phase mode)
    """
    if mode == "two-phase":
        return ([ParticleSet("bed", Suspension(m), x, area, phi=phi0, f=0.0,
                             axisymmetric=axisymmetric),
                 ParticleSet("fluid", NewtonianFluid.from_material(m), x, area, phi=phi0,
                             axisymmetric=axisymmetric)],
                dict(drag=Drag.from_material(m)))
    return ([ParticleSet("bed", Suspension(m, locked=True), x, area, phi=phi0, f=0.0,
                         axisymmetric=axisymmetric)], {})


def bed_phases(m, phi0: float, mode: str) -> list:
    """The (material, m/V [kg/m^3]) of each point set :func:`suspension_bed` makes, for
    :func:`mpm2d.scenes.spec.first_step`: the locked mixture on phi0 rho_s + (1 - phi0) rho_f,
    or the grains on phi0 rho_s and the fluid on (1 - phi0) rho_f."""
    if mode == "two-phase":
        return [(Suspension(m), phi0 * m.rho_s),
                (NewtonianFluid.from_material(m), (1.0 - phi0) * m.rho_f)]
    return [(Suspension(m, locked=True), phi0 * m.rho_s + (1.0 - phi0) * m.rho_f)]
