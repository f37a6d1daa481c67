"""The rheometer's input limits: the physical limits of :mod:`runkit.limits` (each with its
reason, printed with a refusal) as they apply here, the rheometer's own bounds and the numerical
ones (solver tolerances, output rows), each with the reason for its number.

- A duration (``--t-end``, ``--dt``, a program step) is at least 1 ps, the molecular
  relaxation time of the liquid; a program step must also be resolvable by the run's clock
  where it starts (IDA's t is one double): at least :func:`clock_floor` of its start time.
- An imposed rate or stress is 0 (rest) or within the physical range; K0 <= 1e6 (the structure
  changes over a grain displacement of at least a molecular size); oscillation cycles <= 1e5.
- A strain step or amplitude is within [1e-9, 1e6] (runkit.limits.STRAIN_MIN/MAX), a volume
  fraction at least 1e-6 (PHI_MIN, the dilute limit) and below phi_j of the material.
- One :class:`~runkit.params.Param` per quantity: the command line's options (their
  :class:`Quantity`: its static range while parsing, the reasons stated with any refusal), a
  program line and a :class:`~rheometer.transient.Step` (checked once, by the Step or the
  :class:`Start`).
"""

import dataclasses
import math

from runkit import limits as physical
from runkit.limits import CLOCK_RESOLUTION, CLOCK_WHY, clock_floor, ge, gt, le, lt  # noqa: F401
from runkit.params import Option, OutOfRange, Param

TIME_MIN, TIME_MAX = physical.TIME_MIN.value, physical.TIME_MAX.value
STRESS_MIN, STRESS_MAX = physical.STRESS_MIN.value, physical.STRESS_MAX.value
RATE_MIN, RATE_MAX = physical.RATE_MIN.value, physical.RATE_MAX.value
K0_MAX, CYCLES_MAX, STRAIN_MAX = 1e6, 1e5, physical.STRAIN_MAX.value
FREQUENCY_MIN = physical.FREQUENCY_MIN.value

#: the quantities of the options, a program line and a step (0: rest, no stress)
RATE = Param(physical.RATE_MIN, physical.RATE_MAX, unit="1/s", also=(0.0,))
STRESS = Param(physical.STRESS_MIN, physical.STRESS_MAX, unit="Pa", also=(0.0,))
POSITIVE_STRESS = Param(physical.STRESS_MIN, physical.STRESS_MAX, unit="Pa")
POSITIVE_RATE = Param(physical.RATE_MIN, physical.RATE_MAX, unit="1/s")
MODULUS = Param(physical.MODULUS_MIN, physical.MODULUS_MAX, unit="Pa")
K0 = Param(ge(0.0, "K0 = 0: a structure that does not evolve"), le(K0_MAX, (
    "f evolves over a plastic strain 1/K0 (Eq. 5); contacts form and break over a grain "
    "displacement of at least a molecular size (~1 nm), a strain of 1e-6 for 1 mm grains (the "
    "paper's K0: 0.06-1, Tables 5 and 7)")))
DURATION = Param(physical.TIME_MIN, physical.TIME_MAX, unit="s")
STRAIN = Param(physical.STRAIN_MIN, physical.STRAIN_MAX)
AMPLITUDE = {"strain": STRAIN, "stress": POSITIVE_STRESS}
FREQUENCY = Param(physical.FREQUENCY_MIN, physical.FREQUENCY_MAX, unit="Hz")
CYCLES = Param(gt(0.0, "an oscillation runs for some cycles"), le(CYCLES_MAX, (
    "more than any oscillatory test (1e5 cycles at 1 Hz take 28 hours, over which a sample "
    "dries and ages)")))
#: a volume fraction's static range (its top, phi_j of the material, is checked with the
#: material: rheometer.transient.check_phi)
PHI = Param(physical.PHI_MIN, lt(1.0, "a volume fraction: the grains fill less than the whole "
                                      "volume (and less than phi_j of the material)"))
#: the structure f: a fraction of the contacts (Eq. 5)
STRUCTURE = Param(ge(0.0, "f is a fraction"), le(1.0, "f is a fraction"))

#: numerical bounds: IDA's relative tolerance, output rows, an oscillation's sampling
RTOL = Param(ge(1e-13, "500 times the rounding of a double (2.2e-16): tighter, IDA's error "
                       "test fails on rounding alone"),
             le(1e-2, "looser leaves fewer than two correct digits in the results"))
OSCILLATION_RTOL = Param(ge(1e-12, "the harmonics' cycle-to-cycle changes (--tol >= 1e-12) "
                                   "must exceed the solver's error"),
                         le(1e-3, "looser leaves the third harmonic (I3/I1 ~ 1e-3 near the "
                                  "linear limit) within the solver's error"))
TOL = Param(ge(1e-12, "the cycle-to-cycle change of a periodic state is at least the solver's "
                      "error (--rtol >= 1e-12)"),
            le(0.1, "a change of 10% a cycle is not a periodic state"))
SAMPLES = Param(ge(16, "16 samples a cycle resolve the third harmonic (I3/I1) several times "
                       "over its Nyquist limit of 6"),
                le(8192, "a cycle's rows at 8192 samples: finer adds no digits to the "
                         "harmonics and fills the waveform table"), kind="integer")
MAX_CYCLES = Param(ge(2, "a periodic state is two cycles that agree"), CYCLES.hi, kind="integer")
#: output rows: at least both ends and the middle of a step; at most 1e6 (a CSV of ~100 MB)
_ROWS_MAX = le(10 ** 6, "1e6 rows make a CSV of about 100 MB, more than a figure or a fit uses")


def rows(least: int, why: str, most: physical.Bound = _ROWS_MAX) -> Param:
    """The output rows of a command: at least ``least`` (``why``), at most ``most``."""
    return Param(ge(least, why), most, kind="integer")


#: the rows of a transient's step
STEP_ROWS = rows(3, "a step's start, middle and end")


def check_peak_rate(frequency: float, amplitude: float) -> float:
    """A strain oscillation's peak shear rate 2 pi f gamma0 [1/s], held to the rate limit of every
    rate the rheometer imposes (:data:`PEAK_RATE`); ValueError naming the frequency and amplitude."""
    rate = float(f"{2.0 * math.pi * float(frequency) * float(amplitude):.6g}")   # as shown
    return float(PEAK_RATE.check(f"peak shear rate 2 pi f gamma0 at {frequency:g} Hz and "
                                 f"strain amplitude {amplitude:g}", rate))


#: an oscillation's peak rate: any below the rate limit (a slow one is no steady shear)
PEAK_RATE = Param(0.0, physical.RATE_MAX, unit="1/s")


class Quantity(Option):
    """The argparse ``type=`` of an option of the quantity ``param``: its static range checked
    while parsing, or with ``later`` only that it is a finite number (a library function checks
    it, once, naming the option); a refusal of a value that is no finite number states the
    range (``shown``: in words, for a range that depends on other options) with the reasons of
    its bounds (``--rate = nan: must be finite; valid range [1e-09, 1e+09] 1/s, or 0 (WHY;
    WHY)``)."""

    def __init__(self, name: str, param: Param, shown: str = "", later: bool = False):
        super().__init__(name, dataclasses.replace(param, lo=_parsed(param.lo, -math.inf, later),
                                                   hi=_parsed(param.hi, math.inf, later)))
        self.quantity, self.shown = param, shown

    @property
    def range_text(self) -> str:
        return self.shown or self.quantity.range_text(static=True)

    def check(self, value):
        try:
            return super().check(value)
        except OutOfRange:
            raise
        except ValueError as exc:        # Param.check's refusal (the bounds' reasons): our range
            raise ValueError(str(exc).replace(self.param.range_text(static=True),
                                              self.range_text, 1)) from None


def _parsed(bound, edge: float, later: bool):
    """A bound as the parse checks it: a derived one (or any, ``later``) at ``edge`` (+-inf),
    with its reason (stated with the refusal of a value that is no number), or None where the
    reason is derived too."""
    if bound is None or not (later or bound.derived):
        return bound
    return None if callable(bound.why) else physical.Bound(edge, bound.closed, bound.why)
