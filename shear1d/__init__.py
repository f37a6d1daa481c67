"""shear1d: 1-D plane and annular Couette flow of a dense suspension (Baumgarten & Kamrin, Table 8).

Finite volumes across the gap, the full Table 8 granular law through the shared local update
(:func:`rheology.local_update.update_point`), a locked-mixture or a two-phase (Darcy) mode, time
integration on SUNDIALS IDA (banded Jacobian, events) or an explicit scheme, and the dynamic
shear-jamming scene of the paper's Fig. 3.

- :mod:`shear1d.geometry`: plane and annular grids
- :mod:`shear1d.model`: the Couette problem and its method-of-lines right-hand side
- :mod:`shear1d.kernels`: numba kernels
- :mod:`shear1d.integrate`: IDA and explicit integration, stability limit, results, checkpoints
- :mod:`shear1d.dae`: method "dae", the full law as a smooth DAE on IDA (locked mode)
- :mod:`shear1d.analysis`: front position, speed, rigidity
- :mod:`shear1d.analytic`: Newtonian solutions
- :mod:`shear1d.scenes`: ``annular_shear_jamming`` (Fig. 3), ``plane_couette``
- :mod:`shear1d.cli`: the ``shear1d`` command
"""

from .geometry import Grid
from .integrate import Result, solve, stable_time_step
from .model import MODES, Couette
from .scenes import annular_shear_jamming, plane_couette, run_annular

__all__ = ["Grid", "Couette", "MODES", "Result", "solve", "stable_time_step",
           "annular_shear_jamming", "plane_couette", "run_annular"]
