"""Lie-group utilities for SO(3) and SE(3) (angular-first 6-vectors).

Exponential and logarithm maps, adjoints and tangent operators of the
rotation group SO(3) and the rigid-motion group SE(3), written as smooth,
NaN-free functions of the squared rotation angle so that they can be
jitted, vmapped and differentiated (twice) everywhere, including at zero.
"""

from ._se3 import Ad as Ad
from ._se3 import Ad_inv as Ad_inv
from ._se3 import ad as ad
from ._se3 import coad as coad
from ._se3 import exp_se3 as exp_se3
from ._se3 import hat as hat
from ._se3 import inverse_se3 as inverse_se3
from ._se3 import log_se3 as log_se3
from ._se3 import make_se3 as make_se3
from ._se3 import vee as vee
from ._so3 import dexp_so3 as dexp_so3
from ._so3 import dexp_so3_inv as dexp_so3_inv
from ._so3 import exp_so3 as exp_so3
from ._so3 import hat3 as hat3
from ._so3 import log_so3 as log_so3
from ._so3 import vee3 as vee3
from ._tangent import dexp_se3 as dexp_se3
from ._tangent import dexp_se3_dot as dexp_se3_dot
from ._tangent import dexp_se3_inv as dexp_se3_inv
from ._utils import get_epsilon as get_epsilon
