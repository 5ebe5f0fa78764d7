"""Files in and out: trajectories (``.npz`` exact, ``.mat`` SoRoSim) and scene files.

Scene files (TOML) hold a linkage and the settings of its statics and dynamics
(:func:`save_linkage`, :func:`load_linkage`, :func:`load_scene`).

Never traced; scipy is imported only when a ``.mat`` file is read or written. The
trajectory functions are imported on first use (PEP 562): the plots' file helpers
(``sorojax.io._files``) load this package without the integrators (diffrax, ~0.4 s).
"""

import importlib
from typing import TYPE_CHECKING

_LAZY = {
    "load_trajectory": "._trajectory",
    "save_trajectory": "._trajectory",
    "Scene": "._scene",
    "SceneError": "._scene",
    "load_linkage": "._scene",
    "load_scene": "._scene",
    "save_linkage": "._scene",
}
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
    from ._scene import Scene as Scene
    from ._scene import SceneError as SceneError
    from ._scene import load_linkage as load_linkage
    from ._scene import load_scene as load_scene
    from ._scene import save_linkage as save_linkage
    from ._trajectory import load_trajectory as load_trajectory
    from ._trajectory import save_trajectory as save_trajectory
