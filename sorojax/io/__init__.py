"""Files in and out: simulation trajectories as ``.npz`` (exact) or ``.mat`` (SoRoSim).

Never traced; scipy is imported only when a ``.mat`` file is read or written.
"""

from ._trajectory import load_trajectory as load_trajectory
from ._trajectory import save_trajectory as save_trajectory
