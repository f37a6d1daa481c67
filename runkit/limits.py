"""The physical limits every tier's inputs are held to, each with its reason.

A limit is a :class:`Bound`: a value (or a function of the other parameters), whether it is
itself valid, and why it is there; a refusal prints the reason (:mod:`runkit.params`). A bound
is where the physics of the model ends, never where the arithmetic does:

============  ======================  =====================================================
quantity      range                   reason
============  ======================  =====================================================
duration      [1e-12, 1e9] s          1 ps, the molecular relaxation time of the liquid
                                      (water ~1 ps: below it the Newtonian liquid, and the
                                      continuum suspension, has no meaning); 30 years
shear rate    [1e-9, 1e9] 1/s         no steady state within 30 years below (a strain of
                                      order one); past impact and ultrasonic rheometry above
stress        [1e-12, 1e12] Pa        water at 1e-9 1/s carries 1e-12 Pa; 5 x diamond's G
modulus       [1, 1e12] Pa            weakest colloidal gels ~1 Pa (the paper's skeletons:
                                      3.8e5-8.3e7 Pa, Tables 4-7); 5 x diamond's G
viscosity     [1e-5, 1e6] Pa s        a decade below the thinnest liquids; molten polymers
tau*          [1e-8, 1e8] Pa          the DST transition (1e-4..1e4 tau*) within the stresses
density       [1, 1e5] kg/m^3         aerogel, the lightest solid; 4 x osmium (22,600)
grain size    [1e-8, 1e-2] m          a grain many liquid molecules (~0.3 nm) across; beyond
                                      a centimetre, gravel: a granular bed, not a suspension
length        [1e-6, 10] m            the narrowest micro-gap rheometers; a 10 m bed
speed         [1e-18, 1e4] m/s        a molecular size (1 nm) in 30 years; faster than the
                                      shear waves of any grain skeleton (steel ~3e3 m/s)
gravity       [1e-3, 1e3] m/s^2       below the surface gravity of the smallest bodies with a
                                      grain bed (Phobos 5.7e-3); 100 g, a geotechnical
                                      centrifuge
frequency     [1e-9, 1e9] Hz          a period within the longest duration; a period of 1000
                                      molecular relaxation times (the liquid stays Newtonian)
strain        (0, 1e6]                about 1e4 turns of a cone-plate or narrow-gap Couette
                                      (~60-80 per turn): longer, the sample changes (drying,
                                      migration, attrition)
memory        <= 1/2 of what is free  the rest of the machine keeps working
============  ======================  =====================================================

Numerical and resource limits (not physics; stated with their reason): a step of a run starting
at t lasts at least :data:`CLOCK_RESOLUTION` t (:func:`clock_floor`: the run's clock is one
double, and a step's up to 1e6 output rows need distinct times), :data:`MAX_STEPS` explicit steps of a run (a day on one core at the smallest scene),
:data:`MAX_CELL_STEPS` cell-steps of an explicit 1-D run (hours). Sources: the structural
(hydrogen-bond) relaxation time of water, ~1 ps; moduli and densities from standard tables
(diamond G = 478 GPa, osmium 22,590 kg/m^3).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import psutil


@dataclass(frozen=True)
class Bound:
    """One end of a valid range: ``value`` (a number, or a function of the parameters dict),
    ``closed`` (the value itself valid) and ``why`` (the reason, text or a function of the
    parameters; printed with a refusal)."""

    value: float | Callable
    closed: bool = True
    why: str | Callable = ""

    @property
    def derived(self) -> bool:
        return callable(self.value)

    def at(self, params=None) -> tuple[float, bool, str]:
        """(value, closed, reason) at the parameters ``params``."""
        value = self.value(params) if callable(self.value) else self.value
        why = self.why(params) if callable(self.why) else self.why
        return float(value), self.closed, str(why or "")


def ge(x, why="") -> Bound:
    """A closed bound (``x`` itself valid)."""
    return Bound(x, True, why)


def gt(x, why="") -> Bound:
    """An open bound."""
    return Bound(x, False, why)


le, lt = ge, gt

TIME_MIN = ge(1e-12, "1 ps, the molecular relaxation time of the liquid: below it the "
                     "Newtonian liquid, and the continuum suspension, has no meaning")
TIME_MAX = le(1e9, "30 years, past any experiment")
#: a duration starting at t must be at least CLOCK_RESOLUTION t: the clock is one double (t
#: to 2.2e-16 t), and a step writes up to 1e6 rows, 1e-15 t apart at this length: ~5 doubles
CLOCK_RESOLUTION = 1e-9
CLOCK_WHY = (f"{CLOCK_RESOLUTION:g} of the start time: the run's clock is one double (t to "
             "2.2e-16 t) and a step's up to 1e6 output rows must fall on distinct times")
RATE_MIN = ge(1e-9, "1/(30 years): slower shear reaches no steady state within the longest "
                    "duration (a strain of order one)")
RATE_MAX = le(1e9, "past impact and ultrasonic rheometry")
STRESS_MIN = ge(1e-12, "the stress water carries at the slowest rate, 1e-9 1/s")
STRESS_MAX = le(1e12, "five times the shear modulus of diamond: no grain skeleton carries more")
MODULUS_MIN = ge(1.0, "the weakest colloidal gels, ~1 Pa; a softer skeleton carries no stress "
                      "the model describes")
MODULUS_MAX = le(1e12, "five times the shear modulus of diamond")
VISCOSITY_MIN = ge(1e-5, "a decade below the thinnest liquids (~1e-4 Pa s)")
VISCOSITY_MAX = le(1e6, "molten polymers")
TAU_STAR_MIN = ge(1e-8, "the DST transition (1e-4..1e4 tau*) must lie within the stresses "
                        "[1e-12, 1e12] Pa")
TAU_STAR_MAX = le(1e8, "the DST transition (1e-4..1e4 tau*) must lie within the stresses "
                       "[1e-12, 1e12] Pa")
DENSITY_MIN = ge(1.0, "aerogel, the lightest solid")
DENSITY_MAX = le(1e5, "four times osmium, the densest element")
GRAIN_MIN = ge(1e-8, "a grain must be many liquid molecules (~0.3 nm) across for the liquid "
                     "around it to be a continuum")
GRAIN_MAX = le(1e-2, "coarser grains are gravel: a granular bed, not a suspension")
LENGTH_MIN = ge(1e-6, "the narrowest micro-gap rheometers")
LENGTH_MAX = le(10.0, "a 10 m bed, the largest instrument or scene")
SPEED_MIN = ge(1e-18, "a molecular size (1 nm) in 30 years: slower is no motion")
SPEED_MAX = le(1e4, "faster than the shear waves of any grain skeleton (steel ~3e3 m/s)")
GRAVITY_MIN = ge(1e-3, "below the surface gravity of the smallest bodies with a grain bed "
                       "(Phobos 5.7e-3 m/s^2)")
GRAVITY_MAX = le(1e3, "100 g, a geotechnical centrifuge")
PHI_MIN = ge(1e-6, "one grain volume in 1e6: the grains' share of the viscosity (Einstein's "
                   "5/2 phi) is below 1e-5, and the mixture is the liquid")
FREQUENCY_MIN = ge(1.0 / TIME_MAX.value, "a period within the longest duration, 30 years")
FREQUENCY_MAX = le(1e9, "a period of 1 ns, a thousand molecular relaxation times of the "
                        "liquid (~1 ps): above it the liquid is no longer Newtonian (omega "
                        "tau_liquid > 0.01); ultrasonic shear rheometry reaches ~1e8 Hz")
STRAIN_MIN = ge(1e-9, "a displacement of a molecular size (~1 nm) across a 1 m gap; rheometers "
                     "resolve strains down to ~1e-6")
STRAIN_MAX = le(1e6, "about 1e4 turns of a cone-plate or narrow-gap Couette (a strain of ~60-80 "
                     "per turn): sheared longer, the sample itself changes (evaporation at the "
                     "rim, migration out of the gap, grain attrition), which the model leaves "
                     "out")
#: share of the free memory one run may take
MEMORY_FRACTION = 0.5
#: explicit steps of a run (1e8 steps of the smallest mpm2d scene take about a day on one core)
MAX_STEPS = 1e8
#: cell-steps of an explicit 1-D run (about 3 hours at ~1e8 cell-steps per second)
MAX_CELL_STEPS = 1e12


def clock_floor(t_start: float) -> float:
    """Shortest duration [s] of a step starting at ``t_start`` [s] of a run's clock."""
    return max(TIME_MIN.value, CLOCK_RESOLUTION * float(t_start))


def available_memory() -> int:
    """Memory the machine can give without swapping [bytes]."""
    return int(psutil.virtual_memory().available)


def check_memory(name: str, value, nbytes: float, fraction: float = MEMORY_FRACTION) -> None:
    """Refuse a size whose memory estimate ``nbytes`` exceeds ``fraction`` of the available
    memory: ValueError ``"--cells = 1e8 needs about 61 GB (estimate), more than 50% of the 20
    GB available; choose a smaller size"``."""
    avail = available_memory()
    if not nbytes <= fraction * avail:
        raise ValueError(f"{name} = {value} needs about {nbytes / 1e9:.3g} GB (estimate), more "
                         f"than {fraction:.0%} of the {avail / 1e9:.3g} GB available; choose a "
                         "smaller size")
