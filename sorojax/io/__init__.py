"""Files in and out: simulation trajectories as ``.npz`` (exact) or ``.mat`` (SoRoSim).

Never traced; scipy is imported only when a ``.mat`` file is read or written. The
trajectory functions are imported on first use (PEP 562): the plots' file helpers
(``sorojax.io._files``) load this package without the integrators (diffrax, ~0.4 s).
"""

import importlib
from typing import TYPE_CHECKING

_LAZY = {"load_trajectory": "._trajectory", "save_trajectory": "._trajectory"}
__all__ = sorted(_LAZY)


def __getattr__(name: str):
    """Import a public name on first access."""
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'sorojax.io' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


if TYPE_CHECKING:
    from ._trajectory import load_trajectory as load_trajectory
    from ._trajectory import save_trajectory as save_trajectory
