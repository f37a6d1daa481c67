"""Valid ranges of the rheometer's inputs, shared by the command line and the program parser.

Upper bounds (physical, and what the solvers are verified for): stresses and moduli <= 1e12 Pa
(five times the shear modulus of diamond: no grain skeleton is stiffer and no suspension carries
more), shear rates <= 1e9 1/s (well past impact and ultrasonic rheometry), times <= 1e9 s
(30 years), K0 <= 1e6 (the paper's sets use 0.06-1), oscillation cycles <= 1e5 per step (each
cycle is sampled at least 32 times: 3.2e6 rows), strains <= 1e6.
"""

from rheology.cli_common import Number

STRESS_MAX, RATE_MAX, TIME_MAX, K0_MAX = 1e12, 1e9, 1e9, 1e6
CYCLES_MAX, STRAIN_MAX = 1e5, 1e6

#: the checks of a program line's numbers (``Number.check`` raises ValueError naming them)
PROGRAM_RATE = Number("rate", 0.0, RATE_MAX, unit="1/s")
PROGRAM_STRESS = Number("stress", 0.0, STRESS_MAX, unit="Pa")
PROGRAM_AMPLITUDE_STRESS = Number("stress amplitude", 0.0, STRESS_MAX, lo_closed=False,
                                  unit="Pa")
PROGRAM_AMPLITUDE_STRAIN = Number("strain amplitude", 0.0, STRAIN_MAX, lo_closed=False)
PROGRAM_DURATION = Number("duration", 0.0, TIME_MAX, lo_closed=False, unit="s")
PROGRAM_STRAIN = Number("strain", 0.0, STRAIN_MAX, lo_closed=False)
PROGRAM_CYCLES = Number("cycles", 0.0, CYCLES_MAX, lo_closed=False)
