"""Valid ranges of the rheometer's inputs, shared by the command line and the program parser.

The physical limits and their reasons are :mod:`runkit.limits` (durations 1 ps .. 30 years, shear
rates 1e-9 .. 1e9 1/s, stresses 1e-12 .. 1e12 Pa, moduli 1 .. 1e12 Pa); a refusal prints the
reason. Here: the rheometer's own counts and how the limits apply to it.

- A duration (``--t-end``, material-point's ``--dt``, a program step) is at least TIME_MIN = 1 ps,
  the molecular relaxation time of the suspending liquid; it also keeps IDA clear of its stop
  time underflow (any duration below ~1.5e-154 s). A program step must in addition be
  resolvable by the run's clock where it starts (IDA's t is one double through the whole
  program): duration >= CLOCK_RESOLUTION = 1e-9 times its start time (:func:`clock_floor`).
- flow-curve's lower ends: a steady state needs a strain of order one, so a rate below
  RATE_MIN = 1/TIME_MAX has none within 30 years; STRESS_MIN is what water alone carries at it.
- K0 <= 1e6 (the paper's sets use 0.06-1); oscillation cycles <= 1e5 per step (each sampled at
  least 32 times); strains <= 1e6.
- ``--set`` (rheology.materials.FIELD_LIMITS, :func:`check_set`; the Material itself only asks them
  to be positive): tau* in [1e-8, 1e8] Pa (the DST transition, taubar ~ 1e-4..1e4 tau*, within
  the stresses; the paper's sets have 0.1-423 Pa), eta0 in [1e-5, 1e6] Pa s (the paper's
  9e-4-1 Pa s), G, K, kappa as ``--G``, densities [1, 1e5] kg/m^3, grain size [1e-8, 1e-2] m.
"""

from rheology.materials import check_field_limit
from runkit import limits as physical
from runkit.limits import CLOCK_RESOLUTION, clock_floor  # noqa: F401
from runkit.params import Number

TIME_MIN, TIME_MAX = physical.TIME_MIN.value, physical.TIME_MAX.value
STRESS_MIN, STRESS_MAX = physical.STRESS_MIN.value, physical.STRESS_MAX.value
RATE_MIN, RATE_MAX = physical.RATE_MIN.value, physical.RATE_MAX.value
K0_MAX, CYCLES_MAX, STRAIN_MAX = 1e6, 1e5, physical.STRAIN_MAX.value
#: oscillation frequencies from 1/TIME_MAX: a period longer than the longest duration is none
FREQUENCY_MIN = physical.FREQUENCY_MIN.value

#: the checks of a program line's numbers (``Number.check`` raises ValueError naming them)
PROGRAM_RATE = Number("rate", 0.0, physical.RATE_MAX, unit="1/s")
PROGRAM_STRESS = Number("stress", 0.0, physical.STRESS_MAX, unit="Pa")
PROGRAM_AMPLITUDE_STRESS = Number("stress amplitude", 0.0, physical.STRESS_MAX, lo_closed=False,
                                  unit="Pa")
PROGRAM_AMPLITUDE_STRAIN = Number("strain amplitude", 0.0, physical.STRAIN_MAX, lo_closed=False)
PROGRAM_DURATION = Number("duration", physical.TIME_MIN, physical.TIME_MAX, unit="s")
PROGRAM_STRAIN = Number("strain", 0.0, physical.STRAIN_MAX, lo_closed=False)
PROGRAM_CYCLES = Number("cycles", 0.0, CYCLES_MAX, lo_closed=False)


def duration(name: str) -> Number:
    """The ``type=`` of a duration option: [TIME_MIN, TIME_MAX] s with their reasons."""
    return Number(name, physical.TIME_MIN, physical.TIME_MAX, unit="s")


def check_set(overrides: dict, option: str = "--set") -> None:
    """ValueError naming ``option NAME`` for an override outside its physical limits
    (:data:`rheology.materials.FIELD_LIMITS`, the one table of every tier)."""
    for key, value in overrides.items():
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            check_field_limit(f"{option} {key}", key, float(value))
