"""Kinematics: poses, body Jacobians, their time derivatives, strains and twists."""

from ._api import (
    Kinematics as Kinematics,
)
from ._api import (
    forward_kinematics as forward_kinematics,
)
from ._api import (
    jacobians as jacobians,
)
from ._api import (
    jacobians_time_derivative as jacobians_time_derivative,
)
from ._api import (
    kinematics as kinematics,
)
from ._api import (
    screw_strains as screw_strains,
)
from ._api import (
    screw_velocities as screw_velocities,
)
from ._api import (
    tip_pose as tip_pose,
)
from ._fit import strain_coordinates as strain_coordinates
from ._recursion import (
    jacobians_dot as jacobians_dot,
)
from ._recursion import (
    poses_and_jacobians as poses_and_jacobians,
)
from ._recursion import (
    strains as strains,
)
