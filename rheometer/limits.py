"""Valid ranges of the rheometer's inputs, shared by the command line and the program parser.

Upper bounds (physical, and what the solvers are verified for): stresses and moduli <= 1e12 Pa
(five times the shear modulus of diamond: no grain skeleton is stiffer and no suspension carries
more), shear rates <= 1e9 1/s (well past impact and ultrasonic rheometry), times <= 1e9 s
(30 years), K0 <= 1e6 (the paper's sets use 0.06-1), oscillation cycles <= 1e5 per step (each
cycle is sampled at least 32 times: 3.2e6 rows), strains <= 1e6.

Lower bound of every duration (``--t-end``, material-point's ``--dt``, a program step):
TIME_MIN = 1e-12 s (runkit.limits, shared with shear1d's durations). A picosecond is the molecular relaxation time of the suspending liquid (water
~1 ps): below it the Newtonian fluid of the model, and so the continuum suspension, has no meaning.
It also keeps IDA well clear of its own limit: IDA refuses a stop time whose products with the
step underflow, ``(tstop - t)(tout - t) <= 0`` at t = 0, i.e. any duration below ~1.5e-154 s
(``--t-end 1e-300`` failed as "tstop = 1e-300 is behind current t = 0"). A program step must in
addition be resolvable by the run's clock where it starts (IDA's t is one double through the whole
program): duration >= CLOCK_RESOLUTION = 1e-9 times its start time, i.e. >= ~4.5e6 ulps of t, room
for the step's output rows and IDA's internal steps ('rest for 1e-6 s' after 1e6 s of shear made
an output grid that was not increasing).

Lower ends of flow-curve's ranges: a steady state is reached after a strain of order one (the
structure f and the skeleton's elastic strain relax over strains ~1/K0 and taubar/G), so a shear
rate below RATE_MIN = 1/TIME_MAX = 1e-9 1/s has no steady state within the longest time the
rheometer models (30 years); STRESS_MIN = 1e-12 Pa is the stress the suspending liquid alone
(water, 1e-3 Pa s) carries at RATE_MIN. The steady solver brackets its states on a grid of 40
points a decade of taubar from the imposed value to 1e8 tau*: --rate-range 1e-200 1 meant ~12000
grid points per rate (minutes, with no steady state to find); at 1e-9 1/s it is ~1000.

Ranges of the material's scales given with ``--set`` (SET_RANGES; the Material itself only asks
them to be positive). tau* in [1e-8, 1e8] Pa: the DST transition spans taubar ~ 1e-4..1e4 tau*
(the structure f from ~1e-6 to ~1) and must lie within the rheometer's stresses [STRESS_MIN,
STRESS_MAX]; the paper's sets have 0.1-423 Pa (--set tau_star=1e-300 was refused as 'taubar =
0.001 is outside [0, 1e-200]'). eta0 in [1e-5, 1e6] Pa s: from the thinnest liquids (~1e-4 Pa s)
with a decade to spare to molten polymers; the paper's sets have 9e-4-1 Pa s (eta0 = 1e-300
reached a CSV with NaN pressures). G, K, kappa: as --G, (0, STRESS_MAX] Pa.
"""

from runkit import limits as physical
from runkit.params import Number

TIME_MIN, TIME_MAX = physical.TIME_MIN.value, physical.TIME_MAX.value

STRESS_MAX, RATE_MAX, K0_MAX = 1e12, 1e9, 1e6
CYCLES_MAX, STRAIN_MAX = 1e5, 1e6
CLOCK_RESOLUTION = 1e-9
RATE_MIN, STRESS_MIN = 1e-9, 1e-12
#: oscillation frequencies from 1/TIME_MAX: a period longer than the longest duration is none
FREQUENCY_MIN = 1.0 / TIME_MAX

#: the checks of a program line's numbers (``Number.check`` raises ValueError naming them)
PROGRAM_RATE = Number("rate", 0.0, RATE_MAX, unit="1/s")
PROGRAM_STRESS = Number("stress", 0.0, STRESS_MAX, unit="Pa")
PROGRAM_AMPLITUDE_STRESS = Number("stress amplitude", 0.0, STRESS_MAX, lo_closed=False,
                                  unit="Pa")
PROGRAM_AMPLITUDE_STRAIN = Number("strain amplitude", 0.0, STRAIN_MAX, lo_closed=False)
PROGRAM_DURATION = Number("duration", TIME_MIN, TIME_MAX, unit="s")
PROGRAM_STRAIN = Number("strain", 0.0, STRAIN_MAX, lo_closed=False)
PROGRAM_CYCLES = Number("cycles", 0.0, CYCLES_MAX, lo_closed=False)


def duration(name: str) -> Number:
    """The ``type=`` of a duration option: [TIME_MIN, TIME_MAX] s (see the module docstring)."""
    return Number(name, TIME_MIN, TIME_MAX, unit="s")


def clock_floor(t_start: float) -> float:
    """Shortest duration [s] of a step starting at ``t_start`` [s] of the run's clock."""
    return max(TIME_MIN, CLOCK_RESOLUTION * float(t_start))


#: numeric --set parameters whose range the rheometer states (see the module docstring)
SET_RANGES = {
    "tau_star": (1e-8, 1e8, "Pa"),
    "eta0": (1e-5, 1e6, "Pa s"),
    "G": (0.0, STRESS_MAX, "Pa"),
    "K": (0.0, STRESS_MAX, "Pa"),
    "kappa": (0.0, STRESS_MAX, "Pa"),
}


def check_set(overrides: dict, option: str = "--set") -> None:
    """ValueError naming ``option NAME`` for an override outside :data:`SET_RANGES`."""
    for key, value in overrides.items():
        if key in SET_RANGES and value is not None:
            lo, hi, unit = SET_RANGES[key]
            Number(f"{option} {key}", lo, hi, lo_closed=lo > 0.0, unit=unit).check(value)
