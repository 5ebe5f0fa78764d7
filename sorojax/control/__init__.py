"""Control and learning: a pure, jit-able and vmap-able environment."""

from ._env import Environment as Environment
from ._env import EnvState as EnvState
from ._env import rollout as rollout
