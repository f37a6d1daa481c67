"""rheology: the shared constitutive module (Baumgarten & Kamrin, Table 8 and Eqs. 1-37).

Every tier (rheometer, shear1d, mpm2d) takes its physics from here and nowhere else.

- :mod:`rheology.materials`: every parameter set of the paper (``get_material``, ``list_materials``)
- :mod:`rheology.structure`: phi_m, a, f_m, eta_B, H, S and the structure law
- :mod:`rheology.steady`: Eqs. (1)-(2), steady states under stress / rate / mixture-stress control,
  gdot_DST, limit laws, phi from mass fraction
- :mod:`rheology.flow_rule`: invariants, inertial numbers, friction, D^p, yield functions
- :mod:`rheology.local_update`: the implicit Table 8 update over arrays of material points
- :mod:`rheology.fluid`: Beetstra drag, fluid viscosity, pore pressure
- :mod:`rheology.laws`: the point-wise arithmetic shared by all of the above and the kernels
"""

from .fluid import beetstra_F, drag_coefficient, fluid_viscosity, pore_pressure, reynolds_number
from .flow_rule import (dilation_angle, friction, inertial_numbers, invariants, phi_equilibrium,
                        plastic_dissipation, plastic_flow_rate, yield_functions)
from .local_update import (LocalUpdate, elastic_trial, kernel_parameters, local_update, update_points,
                           update_points_serial)
from .materials import (FIG2_MATERIALS, Material, get_material, list_materials, material_names)
from .steady import (SteadyFlow, critical_shear_rate, gdot_dst, granular_viscosity,
                     normal_viscosity, phi_from_mass_fraction, relative_viscosity,
                     steady_state_stress, steady_states_mixture_stress, steady_states_rate,
                     viscosity_high_limit, viscosity_low_limit)
from .structure import (dilatancy_a, eta_B, f_jam, f_max, hardening, phi_m, singh_f, softening,
                        steady_f_of_stress, structure_rate, structure_step, wyart_cates_f)

__all__ = [n for n in dir() if not n.startswith("_")]
