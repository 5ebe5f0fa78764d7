"""External loads: point wrenches (global or follower, constant or functions of t).

Gravity is a field of the linkage; a custom wrench hook is a pure JAX function given
to the linkage (see :class:`sorojax.model.Linkage`).
"""

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ._checks import check_finite, check_shape


class PointWrench(eqx.Module):
    """A point wrench (moment, force) on a link.

    Where it acts: on a rigid link, at the centre of mass (or at its tip with
    ``at_tip=True``); on a soft link, at ``X1`` in [0, 1] of division ``division``
    (1-based), or at the link's tip reference point when ``division`` is None.

    Attributes:
        link: link number, 1-based (as in the linkage's ``parents``; 0 is ground).
        wrench: 6-vector (moment [N m], force [N]), or a pure JAX function of t
            returning one.
        division: 1-based division of a soft link, or None.
        X1: normalised position inside the division (default its end, 1.0).
        follower: if True the wrench is given in the local (body) frame and turns
            with the body; if False it is given in the world frame.
        at_tip: on a rigid link, apply at the tip instead of the CM.
    """

    link: int = eqx.field(static=True)
    wrench: Float[Array, "6"] | Callable
    division: int | None = eqx.field(static=True)
    X1: float = eqx.field(static=True)
    follower: bool = eqx.field(static=True)
    at_tip: bool = eqx.field(static=True)

    def __init__(
        self,
        link: int,
        wrench: ArrayLike | Callable,
        division: int | None = None,
        X1: float = 1.0,
        follower: bool = False,
        at_tip: bool = False,
    ):
        if not callable(wrench):
            check_shape("PointWrench.wrench", wrench, (6,))
            check_finite(
                "PointWrench.wrench",
                wrench,
                "give (moment [N m], force [N]) as finite numbers",
            )
            wrench = jnp.asarray(wrench, dtype=float)
        if not (0.0 <= float(X1) <= 1.0):
            raise ValueError(f"PointWrench.X1 = {X1!r} is not in [0, 1].")
        self.link = int(link)
        self.wrench = wrench
        self.division = None if division is None else int(division)
        self.X1 = float(X1)
        self.follower = bool(follower)
        self.at_tip = bool(at_tip)

    def value(self, t) -> Float[Array, "6"]:
        """The wrench at time ``t``."""
        if callable(self.wrench):
            out = jnp.asarray(self.wrench(t), dtype=float)
            if out.shape != (6,):
                raise ValueError(
                    f"PointWrench.wrench(t) returned shape {out.shape}; expected (6,)."
                )
            return out
        return self.wrench
