"""The rheometer's input limits: the physical limits of :mod:`runkit.limits` (each with its
reason, printed with a refusal) as they apply here, and the rheometer's own counts.

- A duration (``--t-end``, ``--dt``, a program step) is at least 1 ps, the molecular
  relaxation time of the liquid; a program step must also be resolvable by the run's clock
  where it starts (IDA's t is one double): at least :func:`clock_floor` of its start time.
- K0 <= 1e6 (the paper's sets use 0.06-1); oscillation cycles <= 1e5 per step.
- One :class:`~runkit.params.Param` per quantity: the command line's options (their
  :class:`~runkit.params.Option`), a program line and a :class:`~rheometer.transient.Step`
  (checked once, by the Step or the :class:`Start`).
"""

import math

from runkit import limits as physical
from runkit.limits import CLOCK_RESOLUTION, clock_floor, gt, le  # noqa: F401
from runkit.params import Param

TIME_MIN, TIME_MAX = physical.TIME_MIN.value, physical.TIME_MAX.value
STRESS_MIN, STRESS_MAX = physical.STRESS_MIN.value, physical.STRESS_MAX.value
RATE_MIN, RATE_MAX = physical.RATE_MIN.value, physical.RATE_MAX.value
K0_MAX, CYCLES_MAX, STRAIN_MAX = 1e6, 1e5, physical.STRAIN_MAX.value
FREQUENCY_MIN = physical.FREQUENCY_MIN.value

#: the quantities of the options, a program line and a step
RATE = Param(0.0, physical.RATE_MAX, unit="1/s")
STRESS = Param(0.0, physical.STRESS_MAX, unit="Pa")
POSITIVE_STRESS = Param(gt(0.0), physical.STRESS_MAX, unit="Pa")
MODULUS = Param(physical.MODULUS_MIN, physical.MODULUS_MAX, unit="Pa")
K0 = Param(0.0, le(K0_MAX, "six decades above the paper's structure-rate scales, 0.06-1 "
                         "(Tables 5 and 7)"))
DURATION = Param(physical.TIME_MIN, physical.TIME_MAX, unit="s")
STRAIN = Param(gt(0.0), physical.STRAIN_MAX)
AMPLITUDE = {"strain": STRAIN, "stress": POSITIVE_STRESS}
FREQUENCY = Param(physical.FREQUENCY_MIN, physical.FREQUENCY_MAX, unit="Hz")
CYCLES = Param(gt(0.0), le(CYCLES_MAX, "each cycle sampled at least 32 times"))


def check_peak_rate(frequency: float, amplitude: float) -> float:
    """A strain oscillation's peak shear rate 2 pi f gamma0 [1/s], held to :data:`RATE` (the rate
    limit of every rate the rheometer imposes); ValueError naming the frequency and amplitude."""
    rate = float(f"{2.0 * math.pi * float(frequency) * float(amplitude):.6g}")   # as shown
    return float(RATE.check(f"peak shear rate 2 pi f gamma0 at {frequency:g} Hz and strain "
                            f"amplitude {amplitude:g}", rate))
