"""Generalised terms: stiffness, damping and external forces (mass and Coriolis follow)."""

from ._elastic import damping_matrix as damping_matrix, stiffness_matrix as stiffness_matrix
from ._external import (
    external_force as external_force,
    external_force_recursive as external_force_recursive,
    external_wrenches as external_wrenches,
    gravity_wrenches as gravity_wrenches,
    point_wrenches as point_wrenches,
)
from ._generalized import generalized_external_force as generalized_external_force
