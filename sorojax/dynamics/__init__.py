"""Generalised terms: stiffness, damping and external forces (mass and Coriolis follow)."""

from ._elastic import damping_matrix as damping_matrix, stiffness_matrix as stiffness_matrix
from ._external import (
    custom_force as custom_force,
    external_force as external_force,
    gravity_force as gravity_force,
    point_wrench_force as point_wrench_force,
)
from ._generalized import generalized_external_force as generalized_external_force
