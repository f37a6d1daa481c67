"""rheometer: the 0-D virtual rheometer of the Baumgarten & Kamrin model (tier 0).

A homogeneous sample in simple shear, solved as a DAE on SUNDIALS IDA (:mod:`rheometer.model`,
:mod:`rheometer.transient`): steady flow curves, start-up, creep, relaxation (Eqs. 35-37,
Fig. 15) and test programs written as rheologists say them (:mod:`rheometer.program`); and the
material-point mode that drives the full Table 8 local update of :mod:`rheology` through
homogeneous simple shear (:mod:`rheometer.material_point`), with its continuous-time IDA
reference (:mod:`rheometer.tensor_dae`). Command line: ``rheometer`` (:mod:`rheometer.cli`).

Every function returns a pandas DataFrame with units in the column names.
"""

from .material_point import simple_shear_point
from .program import HYSTERESIS_PROGRAM, Program, Start, parse_program
from .protocols import creep, flow_curve, relax, run_program, startup
from .tensor_dae import tensor_reference
from .transient import DEFAULT_G, DEFAULT_K0, Rheometer, State, Step

__all__ = ["flow_curve", "startup", "creep", "relax", "run_program", "parse_program",
           "simple_shear_point", "tensor_reference", "Rheometer", "Step", "State", "Program",
           "Start", "HYSTERESIS_PROGRAM", "DEFAULT_G", "DEFAULT_K0"]
