"""Kinematics: poses, body Jacobians, their time derivatives, strains and twists."""

from ._api import (
    Kinematics as Kinematics,
    forward_kinematics as forward_kinematics,
    jacobians as jacobians,
    jacobians_time_derivative as jacobians_time_derivative,
    kinematics as kinematics,
    screw_strains as screw_strains,
    screw_velocities as screw_velocities,
    tip_pose as tip_pose,
)
from ._recursion import (
    jacobians_dot as jacobians_dot,
    poses_and_jacobians as poses_and_jacobians,
    strains as strains,
)
