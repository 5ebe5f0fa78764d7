"""Actuators: joint actuators (wrench or prescribed coordinate) and cables.

Every actuator owns a block of the actuation input vector ``u`` (in the order the
actuators are given to the linkage):

- :class:`JointActuator` on a link's joint: one entry per joint coordinate. Wrench
  controlled: the entries are the generalised joint forces [N m or N]. Prescribed
  (``prescribed=True``): the entries are the joint coordinates themselves (in dynamics,
  functions of t; velocities and accelerations by autodiff) and the joint efforts
  become unknowns that the solvers return (the manual's mixed forward-inverse model).
- :class:`Cable`: one entry, the tension T [N]; **T > 0 pulls** (SoRoSim's sign is the
  opposite: negate its actuator strengths). A cable is a route through the body: in-body
  :class:`CableSpan` s (a path d(X) = (0, y, z) in the cross-section frame over chosen
  divisions of a soft link) and :class:`CableAnchor` s (points fixed to a link or to
  the ground), joined by straight segments outside the body. Its generalised force is
  ``-T dl/dq`` with ``l(q)`` the cable length: exact for any path (the manual's
  actuation matrix, ``B = -dl/dq``).

Paths are functions of the link-normalised coordinate X in [0, 1] (arc length over the
whole soft link divided by its length), so a path is continuous across divisions.
"""

import abc
from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ._checks import check_positive, check_shape


class AbstractCablePath(eqx.Module):
    """Cable position ``(y, z)`` [m] in the cross-section frame as a function of X."""

    @abc.abstractmethod
    def __call__(self, X) -> Float[Array, "2"]:
        """``(y, z)`` at link-normalised position ``X`` in [0, 1]."""


class ConstantPath(AbstractCablePath):
    """Constant offset ``(y, z)`` (the manual's 'constant')."""

    y: Float[Array, ""]
    z: Float[Array, ""]

    def __init__(self, y: ArrayLike = 0.0, z: ArrayLike = 0.0):
        self.y = jnp.asarray(y, dtype=float)
        self.z = jnp.asarray(z, dtype=float)

    def __call__(self, X):
        """``(y, z)``, the same at every X."""
        return jnp.stack([self.y, self.z]) + 0.0 * X


class ObliquePath(AbstractCablePath):
    """Offset linear in X from ``start`` at X = 0 to ``end`` at X = 1 ('oblique')."""

    start: Float[Array, "2"]
    end: Float[Array, "2"]

    def __init__(self, start: ArrayLike, end: ArrayLike):
        check_shape("ObliquePath.start", start, (2,))
        check_shape("ObliquePath.end", end, (2,))
        self.start = jnp.asarray(start, dtype=float)
        self.end = jnp.asarray(end, dtype=float)

    def __call__(self, X):
        """``start + X (end - start)``."""
        return self.start + X * (self.end - self.start)


class HelicalPath(AbstractCablePath):
    """Helix of ``radius`` about the centre line, ``turns`` turns over the link.

    ``(y, z) = radius (cos(phase + 2 pi turns X), sin(phase + 2 pi turns X))``;
    positive ``turns`` winds counter-clockwise about +x (right-handed helix).
    """

    radius: Float[Array, ""]
    turns: Float[Array, ""]
    phase: Float[Array, ""]

    def __init__(self, radius: ArrayLike, turns: ArrayLike, phase: ArrayLike = 0.0):
        check_positive("HelicalPath.radius", radius, allow_zero=True)
        self.radius = jnp.asarray(radius, dtype=float)
        self.turns = jnp.asarray(turns, dtype=float)
        self.phase = jnp.asarray(phase, dtype=float)

    def __call__(self, X):
        """Point of the helix at X."""
        a = self.phase + 2.0 * jnp.pi * self.turns * X
        return self.radius * jnp.stack([jnp.cos(a), jnp.sin(a)])


class CustomPath(AbstractCablePath):
    """A user path: a pure JAX function ``X -> (y, z)`` ('custom').

    ``params`` (any pytree of arrays) is passed as the second argument, so gradients
    reach it: ``fn(X, params)``.
    """

    fn: Callable = eqx.field(static=True)
    params: object

    def __init__(self, fn: Callable, params=None):
        if not callable(fn):
            raise ValueError(
                f"CustomPath.fn = {fn!r}: give a function (X, params) -> (y, z)."
            )
        self.fn = fn
        self.params = params

    def __call__(self, X):
        """``fn(X, params)`` as a (2,) array."""
        out = jnp.asarray(self.fn(X, self.params), dtype=float)
        if out.shape != (2,):
            raise ValueError(
                f"CustomPath.fn returned shape {out.shape}; expected (2,) = (y, z)."
            )
        return out


class CableSpan(eqx.Module):
    """The part of a cable inside soft link ``link``, over divisions ``divisions``.

    Attributes:
        link: 1-based number of a soft link.
        path: an :class:`AbstractCablePath` (of the link-normalised X).
        divisions: ``(first, last)`` 1-based divisions spanned (inclusive); default
            all of the link's divisions (the manual's Sdiv, Ediv).
    """

    link: int = eqx.field(static=True)
    path: AbstractCablePath
    divisions: tuple[int, int] | None = eqx.field(static=True)

    def __init__(
        self,
        link: int,
        path: AbstractCablePath,
        divisions: tuple[int, int] | None = None,
    ):
        if not isinstance(path, AbstractCablePath):
            raise ValueError(
                f"CableSpan.path = {path!r}: give a ConstantPath, ObliquePath, "
                "HelicalPath or CustomPath."
            )
        if divisions is not None:
            divisions = (int(divisions[0]), int(divisions[1]))
            if divisions[0] < 1 or divisions[1] < divisions[0]:
                raise ValueError(
                    f"CableSpan.divisions = {divisions!r}: give (first, last) with "
                    "1 <= first <= last (1-based division numbers)."
                )
        self.link = int(link)
        self.path = path
        self.divisions = divisions


class CableAnchor(eqx.Module):
    """A point a cable passes through (or ends at), fixed to a link or the ground.

    Where: as for :class:`~sorojax.PointWrench` (a soft link's division and X1, its tip
    when ``division`` is None; a rigid link's CM, or tip with ``at_tip``); ``link = 0``
    is the ground and ``offset`` is then a world point.

    Attributes:
        link: 1-based link number, 0 for the ground.
        offset: (3,) position in the local frame of that point [m] (world for ground).
        division: 1-based division of a soft link, or None.
        X1: position inside the division.
        at_tip: on a rigid link, the tip instead of the CM.
    """

    link: int = eqx.field(static=True)
    offset: Float[Array, "3"]
    division: int | None = eqx.field(static=True)
    X1: float = eqx.field(static=True)
    at_tip: bool = eqx.field(static=True)

    def __init__(
        self,
        link: int,
        offset: ArrayLike = (0.0, 0.0, 0.0),
        division: int | None = None,
        X1: float = 1.0,
        at_tip: bool = False,
    ):
        check_shape("CableAnchor.offset", offset, (3,))
        if not (0.0 <= float(X1) <= 1.0):
            raise ValueError(f"CableAnchor.X1 = {X1!r} is not in [0, 1].")
        self.link = int(link)
        self.offset = jnp.asarray(offset, dtype=float)
        self.division = None if division is None else int(division)
        self.X1 = float(X1)
        self.at_tip = bool(at_tip)


class Cable(eqx.Module):
    """A cable: a route of spans and anchors; input = tension T [N], T > 0 pulls.

    Consecutive route elements are joined by straight segments (outside the body, or
    zero-length where a span continues into the next link). A cable fully inside the
    body is one or more :class:`CableSpan`; a gripper tendon is a chain of
    :class:`CableAnchor` s, e.g. from a ground pulley along the phalanges.

    Attributes:
        route: tuple of :class:`CableSpan` / :class:`CableAnchor`.
        name: label for plots and results.
    """

    route: tuple[CableSpan | CableAnchor, ...]
    name: str = eqx.field(static=True)

    def __init__(self, route, name: str = "cable"):
        if isinstance(route, CableSpan | CableAnchor):
            route = (route,)
        route = tuple(route)
        if not route or not all(isinstance(r, CableSpan | CableAnchor) for r in route):
            raise ValueError(
                f"Cable.route = {route!r}: give one or more CableSpan / CableAnchor."
            )
        if len(route) == 1 and isinstance(route[0], CableAnchor):
            raise ValueError(
                "Cable.route has a single anchor: a cable needs a span or at least "
                "two anchors."
            )
        self.route = route
        self.name = name

    @property
    def n_inputs(self) -> int:
        """One input: the tension."""
        return 1


class JointActuator(eqx.Module):
    """Actuation of link ``link``'s joint: by wrench, or by prescribed coordinates.

    Attributes:
        link: 1-based link number whose base joint is actuated.
        prescribed: False: the inputs are joint forces (wrench controlled, 'W');
            True: the inputs are the joint coordinates (the manual's 'Q'), and the
            efforts are solved for.
        n_inputs: number of joint coordinates (set by the linkage).
    """

    link: int = eqx.field(static=True)
    prescribed: bool = eqx.field(static=True)
    n_inputs: int = eqx.field(static=True)

    def __init__(self, link: int, prescribed: bool = False, n_inputs: int = -1):
        self.link = int(link)
        self.prescribed = bool(prescribed)
        self.n_inputs = int(n_inputs)


Actuator = Cable | JointActuator
