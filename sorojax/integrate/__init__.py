"""Dynamics integration with diffrax: :func:`simulate` and its :class:`Trajectory`."""

from ._rosenbrock import ROS34PW2 as ROS34PW2
from ._rosenbrock import MechanicalTerm as MechanicalTerm
from ._rosenbrock import RosenbrockEuler as RosenbrockEuler
from ._rosenbrock import RosenbrockTableau as RosenbrockTableau
from ._rosenbrock import RosenbrockW as RosenbrockW
from ._simulate import DEFAULT_SOLVER as DEFAULT_SOLVER
from ._simulate import SOLVERS as SOLVERS
from ._simulate import auto_solver as auto_solver
from ._simulate import simulate as simulate
from ._simulate import stiffness_estimate as stiffness_estimate
from ._trajectory import Trajectory as Trajectory
