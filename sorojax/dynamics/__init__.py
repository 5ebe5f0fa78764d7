"""Generalised terms: stiffness, damping and external forces (M, C: issue 3)."""

from ._elastic import damping_matrix as damping_matrix
from ._elastic import stiffness_matrix as stiffness_matrix
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
