"""Default volume fractions per material: one rule for every command of every tier (issue 15).

A set with DST (a finite buckling resistance eta_B, Eq. 9: the Table 2-7 sets and Singh (b)) gets
``phi = phi_c + s (phi_j - phi_c)`` with ``s = 0.45, 0.65, 0.85``: all three inside the DST window
phi_c <= phi < phi_j (Hermes 2016: 0.48, 0.50, 0.52). A set without DST (eta_B infinite: Singh
(a), which shear-jams above phi_c) gets ``s = -1.5, -0.75, -0.25``: below phi_c, where it flows at
every stress. Each value is rounded to the nearest 0.005 (and kept inside (0, phi_j)). A command
or scene with one fraction takes the middle one.
"""

from __future__ import annotations

from .materials import Material, get_material

DST_POSITIONS = (0.45, 0.65, 0.85)
NO_DST_POSITIONS = (-1.5, -0.75, -0.25)
RULE = ("default phi: sets with DST (finite eta_B) phi_c + (0.45, 0.65, 0.85)(phi_j - phi_c), "
        "sets without DST (Singh (a)) phi_c + (-1.5, -0.75, -0.25)(phi_j - phi_c), rounded to "
        "0.005; one-phi commands take the middle one")


def has_dst(material) -> bool:
    """Whether the set shows DST: a finite buckling resistance eta_B (Eq. 9)."""
    m = material if isinstance(material, Material) else get_material(material)
    return (m.varphi1 + m.varphi2) > 0


def default_fractions(material) -> list[float]:
    """The three default volume fractions of ``material`` (name or Material), ascending."""
    m = material if isinstance(material, Material) else get_material(material)
    s = DST_POSITIONS if has_dst(m) else NO_DST_POSITIONS
    out = []
    for x in s:
        phi = round((m.phi_c + x * (m.phi_j - m.phi_c)) / 0.005) * 0.005
        out.append(float(round(min(max(phi, 0.005), m.phi_j - 0.005), 6)))
    return out


def default_fraction(material) -> float:
    """The single default volume fraction (the middle of :func:`default_fractions`)."""
    return default_fractions(material)[1]
