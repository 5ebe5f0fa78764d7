"""sorojax: differentiable simulation of hybrid soft/rigid robots (GVS approach) in JAX.

Conventions: SI units; 6-vectors angular first ``(wx, wy, wz, vx, vy, vz)``; wrenches
``(moment, force)``; rod axis local x; links numbered from 1 (0 = ground).
"""

from ._results import RESULTS as RESULTS, StaticsSolution as StaticsSolution
from .dynamics import (
    damping_matrix as damping_matrix,
    generalized_external_force as generalized_external_force,
    stiffness_matrix as stiffness_matrix,
)
from .kinematics import (
    Kinematics as Kinematics,
    forward_kinematics as forward_kinematics,
    jacobians as jacobians,
    jacobians_time_derivative as jacobians_time_derivative,
    kinematics as kinematics,
    screw_strains as screw_strains,
    screw_velocities as screw_velocities,
    tip_pose as tip_pose,
)
from .model import (
    CircularSection as CircularSection,
    CustomBasis as CustomBasis,
    Division as Division,
    EllipticalSection as EllipticalSection,
    Joint as Joint,
    LegendreBasis as LegendreBasis,
    Linkage as Linkage,
    Material as Material,
    MonomialBasis as MonomialBasis,
    PointWrench as PointWrench,
    RectangularSection as RectangularSection,
    RigidLink as RigidLink,
    SoftLink as SoftLink,
    translation as translation,
)
from .model._precompute import precompute as precompute
from .statics import solve_statics as solve_statics

__version__ = "0.1.0"
