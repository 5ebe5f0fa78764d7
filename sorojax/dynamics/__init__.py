"""Generalised terms: M, C, K, D, external forces, equations of motion, energies."""

from ._actuation import actuation_matrix as actuation_matrix
from ._actuation import cable_lengths as cable_lengths
from ._constraints import closure_errors as closure_errors
from ._constraints import constraint_jacobian as constraint_jacobian
from ._constraints import numerical_rank as numerical_rank
from ._contact import ContactState as ContactState
from ._contact import contact_energy as contact_energy
from ._contact import contact_state as contact_state
from ._elastic import damping_matrix as damping_matrix
from ._elastic import stiffness_matrix as stiffness_matrix
from ._energy import elastic_energy as elastic_energy
from ._energy import gravitational_energy as gravitational_energy
from ._energy import kinetic_energy as kinetic_energy
from ._energy import total_energy as total_energy
from ._eom import equations_of_motion as equations_of_motion
from ._eom import forward_dynamics as forward_dynamics
from ._external import (
    external_force as external_force,
)
from ._external import (
    external_force_recursive as external_force_recursive,
)
from ._external import (
    external_wrenches as external_wrenches,
)
from ._external import (
    gravity_wrenches as gravity_wrenches,
)
from ._external import (
    point_wrenches as point_wrenches,
)
from ._generalized import generalized_external_force as generalized_external_force
from ._mass import coriolis_force as coriolis_force
from ._mass import coriolis_matrix as coriolis_matrix
from ._mass import mass_matrix as mass_matrix
