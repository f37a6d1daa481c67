"""The small-elastic-strain limit of the Table 8 law, shared by every tier.

The granular stress of Baumgarten & Kamrin's model (Table 8) is hypoelastic: a Jaumann rate of a
linear elastic law with shear modulus G and bulk modulus K, i.e. a law for SMALL elastic strains.
The elastic shear strain of the skeleton is taubar/G (and its volumetric strain p/K); a run in
which it grows past :data:`ELASTIC_STRAIN_LIMIT` (10 %) uses the law outside its range: its
stresses (up to G times any strain the drive imposes) mean nothing. ``shear1d`` bounds its wall
speed to 0.1 c_s and its wall stress to 0.1 G for this reason (an impulsively moved wall sends a
shear wave of elastic strain u/c_s); the rheometer and the shear1d scene runs check the strain
reached.

:func:`past_elastic_limit` finds the first row of a run past the limit and describes it as the
run's end (:class:`rheology.run_end.RunEnd`: the run keeps its rows before it, see
:mod:`rheology.run_end`), naming the limit, the strain reached, the time and what to change.
"""

from __future__ import annotations

import numpy as np
from .run_end import RunEnd

#: Largest elastic strain (taubar/G, p/K) at which the hypoelastic law is used.
ELASTIC_STRAIN_LIMIT = 0.1
#: Relative margin on the limit for round-off and solver tolerance (a run held exactly at the
#: limit, e.g. a relaxation from taubar = 0.1 G, is not refused for 1e-12 of drift).
MARGIN = 1e-6


def elastic_strain_limit_stress(modulus: float) -> float:
    """The largest stress [Pa] the limit allows on ``modulus`` [Pa]: ELASTIC_STRAIN_LIMIT * G."""
    return ELASTIC_STRAIN_LIMIT * float(modulus)


def past_elastic_limit(t, stress, modulus: float, *, stress_name: str = "taubar",
                       modulus_name: str = "G", where: str = "", advice: str = ""):
    """The first row where ``|stress|/modulus`` exceeds :data:`ELASTIC_STRAIN_LIMIT`, as the end
    of the run: ``(index, RunEnd)``, or None when every row is within the limit.

    Parameters
    ----------
    t, stress : array_like, shape (n,)
        Times [s] of the rows; granular shear stress taubar or pressure p [Pa] at those times.
    modulus : float
        G or K [Pa].
    stress_name, modulus_name : str
        Names in the message (``"taubar"``, ``"G"``; ``"p"``, ``"K"``).
    where : str
        What ran (e.g. ``"startup at 1e9 1/s, phi = 0.5"``), put in front of the reason.
    advice : str
        What to change (e.g. ``"lower --rate or --t-end, or raise --G"``).

    Returns
    -------
    (int, RunEnd) or None
        The index of the first row past the limit and the end (kind ``"validity_limit"``):
        ``time_s`` of the row before it (None for the first row), ``value`` its strain,
        ``past_s`` its time; the reason is one line with the limit, the strain (to the digits
        that tell it from the limit) and stress reached, the modulus, the time of the row the
        run ends at and of the crossing between the two rows (linear interpolation), ``advice``.
    """
    t = np.asarray(t, dtype=float).ravel()
    s = np.abs(np.asarray(stress, dtype=float).ravel())
    strain = s / float(modulus)
    over = np.flatnonzero(strain > ELASTIC_STRAIN_LIMIT * (1.0 + MARGIN))
    if over.size == 0:
        return None
    i = int(over[0])
    head = f"{where}: " if where else ""
    # the strain at as many digits as tell it from the limit (0.1003, not 0.1)
    value = next((f"{strain[i]:.{k}g}" for k in range(3, 10)
                  if float(f"{strain[i]:.{k}g}") > ELASTIC_STRAIN_LIMIT), repr(float(strain[i])))
    if i > 0:       # the run ends at the row before; the crossing by linear interpolation
        a, b = strain[i - 1], strain[i]
        tc = t[i - 1] + (t[i] - t[i - 1]) * (ELASTIC_STRAIN_LIMIT - a) / (b - a)
        ends = (f"; the run ends at the row before, t = {t[i - 1]:.6g} s, the last within the "
                f"limit (the strain passes it between these rows, from t ~ {tc:.4g} s by linear "
                f"interpolation)")
    else:
        ends = "; the first row is past it: no row is kept"
    reason = (
        f"{head}elastic strain {stress_name}/{modulus_name} = {value} at t = {t[i]:.6g} s "
        f"({stress_name} = {s[i]:.4g} Pa, {modulus_name} = {float(modulus):.4g} Pa) exceeds the "
        f"small-elastic-strain limit {ELASTIC_STRAIN_LIMIT:g} of the hypoelastic law "
        f"({stress_name} <= {elastic_strain_limit_stress(modulus):.4g} Pa){ends}"
        + (f"; {advice}" if advice else ""))
    return i, RunEnd("validity_limit", reason, float(t[i - 1]) if i > 0 else None,
                     f"elastic strain {stress_name}/{modulus_name}", float(strain[i]),
                     ELASTIC_STRAIN_LIMIT, float(t[i]))
