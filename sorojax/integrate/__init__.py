"""Dynamics integration with diffrax: :func:`simulate` and its :class:`Trajectory`."""

from ._simulate import DEFAULT_SOLVER as DEFAULT_SOLVER
from ._simulate import SOLVERS as SOLVERS
from ._simulate import simulate as simulate
from ._simulate import stiffness_estimate as stiffness_estimate
from ._trajectory import Trajectory as Trajectory
