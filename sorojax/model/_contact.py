"""Contact: obstacles, the contact law, rigid contact shapes and the contact set.

What lives here is the model side of contact (immutable descriptions, their checks and
the static sample tables); the forces are computed in :mod:`sorojax.dynamics._contact`.

Geometry. A soft link's surface is a swept sphere along its centre line: contact is
checked at sample points (significant points of the layout, so their kinematics are
exact) spaced at most ``spacing`` apart, each a sphere of the section's radius (the
larger half-width of the section, or a radius the user gives). A rigid link carries a
:class:`ContactSphere`, :class:`ContactCapsule` or :class:`ContactBox` (points with
radii in its centre-of-mass frame). Obstacles (:class:`Plane`, :class:`Sphere`,
:class:`Capsule`, :class:`Box`) are signed-distance functions in their own frame,
placed by a pose, or moved by a function of time. Rod-rod and self-contact are
checked between the segments that join consecutive samples (closest points of two
segments, so that two crossing rods cannot slip between samples).

Law (:class:`ContactLaw`). With the penetration ``d`` (positive when overlapping,
[m]) the normal force is a penalty smoothed over the depth ``delta``::

    f_n(d) = 0                       d <= 0
             k d^2 / (2 delta)       0 < d < delta
             k (d - delta / 2)       d >= delta

(continuously differentiable, with the potential ``U(d) = int_0^d f_n``: conservative),
plus a damping ``-c s(d) v_n`` (``s`` a smooth step from 0 at d = 0 to 1 at
``d = delta``; it always opposes the normal velocity, so it only dissipates) and a
regularised Coulomb friction ``-mu(|v_t|) f_n v_t / sqrt(|v_t|^2 + v_s^2)`` with
``mu`` going from the static coefficient at rest to the kinetic one above the
Stribeck velocity (and, with a stick load, ``v_s`` growing with ``f_n`` past it).
On soft links the law is per unit length (k [N/m^2], c [N s/m^2]: each sample
carries the length it stands for); on rigid contact points, rod-rod segment pairs
and self-contact it is per point (k [N/m], c [N s/m]).
"""

import math
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._checks import check_finite, check_se3, check_shape, is_concrete
from ._hook import Hook, as_hook


def _safe_norm(x: Array, axis=-1) -> Array:
    """Euclidean norm with a finite gradient at zero."""
    sq = jnp.sum(x * x, axis=axis)
    pos = sq > 0
    return jnp.where(pos, jnp.sqrt(jnp.where(pos, sq, 1.0)), 0.0)


def _check_nonnegative(field: str, value, strict: bool = False) -> None:
    if not is_concrete(value):
        return
    arr = np.asarray(value, dtype=float)
    bad = ~np.isfinite(arr) | ((arr <= 0) if strict else (arr < 0))
    if np.any(bad):
        need = "> 0" if strict else ">= 0"
        raise ValueError(
            f"{field} = {value!r} is not allowed: give a finite value {need}."
        )


def _scalar(field: str, value, strict: bool) -> Array:
    check_shape(field, value, ())
    _check_nonnegative(field, value, strict)
    with jax.ensure_compile_time_eval():
        return jnp.asarray(value, dtype=float)


# ---------------------------------------------------------------------------- law
BARRIER_FLOOR = 1e-2
"""Fraction of the barrier's reach below which its force continues linearly."""


def _barrier(law, d: Array) -> tuple[Array, Array]:
    """``(f, U)`` of the barrier law at penetration ``d`` (gap ``g = -d``)."""
    k, gh = law.stiffness, law.smoothing
    d = jnp.asarray(d, dtype=k.dtype)
    xm = BARRIER_FLOOR
    # the log's argument kept in (xm, 1], so that no branch makes a NaN gradient
    x = jnp.clip(-d / gh, xm, 1.0)
    lx = jnp.log(x)
    f = k * gh * (2.0 * (x - 1.0) * lx + (x - 1.0) ** 2 / x)
    u = -k * gh * gh * (x - 1.0) ** 2 * jnp.log(x)
    # linear continuation below x_m: slope df/dg there (negative), in the gap g
    lm = jnp.log(xm)
    fm = k * gh * (2.0 * (xm - 1.0) * lm + (xm - 1.0) ** 2 / xm)
    um = -k * gh * gh * (xm - 1.0) ** 2 * lm
    sm = k * (2.0 * lm + 4.0 * (xm - 1.0) / xm - (xm - 1.0) ** 2 / xm**2)
    e = -d - xm * gh  # g - g_m (negative below the floor)
    deep = e < 0.0
    f = jnp.where(deep, fm + sm * e, f)
    u = jnp.where(deep, um - fm * e - 0.5 * sm * e * e, u)
    return f, u


class ContactLaw(eqx.Module):
    """Normal force (smoothed penalty or barrier), damping and regularised friction.

    Two normal laws (``kind``), both continuously differentiable with a potential:

    - ``"penalty"`` (default): no force until the surfaces overlap, then a force
      that ramps quadratically over ``smoothing`` and rises with slope ``stiffness``
      beyond. The surfaces overlap by about ``f / k + smoothing / 2`` under a load f.
    - ``"barrier"``: a logarithmic barrier that acts across a gap, from ``smoothing``
      (its reach, g_hat) down: ``f(g) = k g_hat (2 (x - 1) ln x + (x - 1)^2 / x)``,
      ``x = g / g_hat``, potential ``-k g_hat^2 (x - 1)^2 ln x``. The force grows
      without bound as the gap closes (about ``k g_hat / x`` for small x), so under
      any load the surfaces stay apart: the equilibrium gap is about
      ``k g_hat^2 / f`` once ``f >> k g_hat``. Below ``x = 1e-2`` of the reach the
      force continues linearly with its slope there (a step of an integrator that
      overshoots meets a very stiff penalty instead of a logarithm of a negative
      number). The body appears larger by up to ``g_hat``: choose ``g_hat`` small
      against the radii and k so that ``k g_hat`` is below the loads per length.

    ``benchmarks/contact.py`` (``laws``) measures the two against each other on the
    heavy cantilever resting on a floor (statics) and on a rod dropped onto it
    (dynamics).

    Attributes:
        stiffness: k, for the penalty the slope of the normal force per penetration
            once deeper than ``smoothing``; for the barrier its scale (above). Per
            unit length on soft links [N/m^2], per point on rigid links and segment
            pairs [N/m]. Choose the penalty's k so that the penetration is small
            against the radii (e.g. 1e-3 of them).
        smoothing: delta [m]. Penalty: the depth over which the stiffness ramps
            from 0 to k (smaller is closer to a hard contact and stiffer to
            integrate; 1e-2 to 1e-1 of the expected penetration is a good start).
            Barrier: its reach g_hat, the gap at which the force starts.
        damping: c, normal damping per unit normal velocity [N s/m^2 per length on
            soft links, N s/m per point], switched on smoothly over delta (the
            penalty's ramp; the barrier's outer half of its reach).
        static_friction: mu_s >= 0, the friction coefficient at rest.
        kinetic_friction: mu_k >= 0, the coefficient when sliding (default mu_s).
        stick_velocity: v_s [m/s] > 0, the slip speed below which friction is
            regularised (viscous): a body held by friction below its limit creeps
            at about ``v_s r / sqrt(1 - r^2)``, r the ratio of the tangential load
            to its limit. Smaller holds better and is stiffer to integrate.
        stribeck_velocity: [m/s] > 0, the slip speed over which mu goes from
            mu_s to mu_k (``mu = mu_k + (mu_s - mu_k) / (1 + (v / v_str)^2)``).
        stick_load: optional f* > 0 [N/m on soft links, N per point], the normal
            force past which the stick velocity grows with it: friction meets
            ``v_s sqrt(1 + (f_n / f*)^2)`` instead of v_s, so that its viscous
            slope ``mu f_n / v_s`` stays below ``mu f* / v_s`` however hard the
            surfaces press. An impact's normal force (many times the resting load)
            then does not make sticking friction a damping faster than the
            contact's own scales (which would bound an explicit integrator's
            step); sliding friction (``|v_t|`` well above the stick velocity) is
            unchanged, and a contact pressed by less than f* holds as with v_s (its
            creep grows by ``(f_n / f*)^2 / 2`` of itself). Choose it a few times
            the largest resting load. None: the stick velocity is v_s at every
            load.
        forward_friction: optional mu_f >= 0 for slip along the body's +x axis
            (a rod's tangent, a rigid link's CM-frame x) on an obstacle: anisotropic
            friction, as scales or bristles give (a crawler, a snake). The slip's
            component along that axis meets ``w mu_f + (1 - w) mu`` with
            ``w = (1 + tanh(v_x / v_s)) / 2`` (mu_f forward, mu backward), the rest
            of the slip mu. None: isotropic.
        kind: ``"penalty"`` or ``"barrier"`` (static).
    """

    stiffness: Float[Array, ""]
    smoothing: Float[Array, ""]
    damping: Float[Array, ""]
    static_friction: Float[Array, ""]
    kinetic_friction: Float[Array, ""]
    stick_velocity: Float[Array, ""]
    stribeck_velocity: Float[Array, ""]
    forward_friction: Float[Array, ""] | None
    stick_load: Float[Array, ""] | None
    kind: str = eqx.field(static=True)

    def __init__(
        self,
        stiffness: ArrayLike,
        smoothing: ArrayLike = 1e-4,
        damping: ArrayLike = 0.0,
        static_friction: ArrayLike = 0.0,
        kinetic_friction: ArrayLike | None = None,
        stick_velocity: ArrayLike = 1e-3,
        stribeck_velocity: ArrayLike = 1e-2,
        forward_friction: ArrayLike | None = None,
        kind: str = "penalty",
        stick_load: ArrayLike | None = None,
    ):
        if kind not in ("penalty", "barrier"):
            raise ValueError(
                f"ContactLaw.kind must be 'penalty' or 'barrier', got {kind!r}."
            )
        self.kind = kind
        self.stiffness = _scalar("ContactLaw.stiffness", stiffness, True)
        self.smoothing = _scalar("ContactLaw.smoothing", smoothing, True)
        self.damping = _scalar("ContactLaw.damping", damping, False)
        self.static_friction = _scalar(
            "ContactLaw.static_friction", static_friction, False
        )
        if kinetic_friction is None:
            kinetic_friction = self.static_friction
        self.kinetic_friction = _scalar(
            "ContactLaw.kinetic_friction", kinetic_friction, False
        )
        self.stick_velocity = _scalar("ContactLaw.stick_velocity", stick_velocity, True)
        self.stribeck_velocity = _scalar(
            "ContactLaw.stribeck_velocity", stribeck_velocity, True
        )
        self.forward_friction = (
            None
            if forward_friction is None
            else _scalar("ContactLaw.forward_friction", forward_friction, False)
        )
        self.stick_load = (
            None
            if stick_load is None
            else _scalar("ContactLaw.stick_load", stick_load, True)
        )

    def normal_force(self, d: Array) -> Array:
        """``f_n(d)``: the elastic normal force at penetration ``d`` (gap: d < 0)."""
        if self.kind == "barrier":
            return _barrier(self, d)[0]
        k, delta = self.stiffness, self.smoothing
        dp = jnp.maximum(d, 0.0)
        ramp = k * dp * dp / (2.0 * delta)
        return jnp.where(d >= delta, k * (d - 0.5 * delta), ramp)

    def potential(self, d: Array) -> Array:
        """``U(d) = int f_n``: the elastic contact energy (per length or point).

        Zero where the law does not act.
        """
        if self.kind == "barrier":
            return _barrier(self, d)[1]
        k, delta = self.stiffness, self.smoothing
        dp = jnp.maximum(d, 0.0)
        cubic = k * dp**3 / (6.0 * delta)
        full = k * (0.5 * d * d - 0.5 * delta * d + delta * delta / 6.0)
        return jnp.where(d >= delta, full, cubic)

    def penetration(self, f: Array) -> Array:
        """The penetration at which the elastic normal force is ``f`` (inverse law).

        The barrier's is negative, a gap (60 bisections of its monotone force).
        """
        if self.kind == "barrier":
            f = jnp.asarray(f, dtype=self.stiffness.dtype)
            lo = jnp.full_like(f, -self.smoothing)  # the force's onset
            hi = jnp.full_like(f, 0.0)
            hi = jnp.maximum(hi, (f - _barrier(self, hi)[0]) / self.stiffness)

            def halve(_, b):
                lo, hi = b
                mid = 0.5 * (lo + hi)
                below = _barrier(self, mid)[0] < f
                return jnp.where(below, mid, lo), jnp.where(below, hi, mid)

            lo, hi = jax.lax.fori_loop(0, 60, halve, (lo, hi))
            return 0.5 * (lo + hi)
        k, delta = self.stiffness, self.smoothing
        small = jnp.sqrt(2.0 * delta * jnp.maximum(f, 0.0) / k)
        return jnp.where(f >= 0.5 * k * delta, f / k + 0.5 * delta, small)

    def ramp(self, d: Array) -> Array:
        """Smooth step from 0 to 1 that switches damping on.

        Over ``[0, delta]`` of penetration (penalty), over the outer half of the
        barrier's reach.
        """
        if self.kind == "barrier":
            s = jnp.clip(2.0 * (d + self.smoothing) / self.smoothing, 0.0, 1.0)
        else:
            s = jnp.clip(d / self.smoothing, 0.0, 1.0)
        return s * s * (3.0 - 2.0 * s)

    def stick_speed_squared(self, f_n: Array) -> Array:
        """The squared stick velocity friction meets under normal force ``f_n``.

        ``v_s^2``, or ``v_s^2 (1 + (f_n / f*)^2)`` with a :attr:`stick_load` f*.
        """
        vs2 = self.stick_velocity**2
        if self.stick_load is None:
            return vs2
        r = f_n / self.stick_load
        return vs2 * (1.0 + r * r)

    def friction_coefficient(self, speed: Array) -> Array:
        """``mu`` at slip speed ``speed`` (static at rest, kinetic when sliding)."""
        x = speed / self.stribeck_velocity
        return self.kinetic_friction + (
            self.static_friction - self.kinetic_friction
        ) / (1.0 + x * x)


# ---------------------------------------------------------------------- obstacles
def _motion_pose(motion: Hook | None, pose: Array, t) -> tuple[Array, Array]:
    """``(G, Gdot)``: the obstacle's world pose at ``t`` and its time derivative."""
    if motion is None:
        return pose, jnp.zeros_like(pose)
    t = jnp.asarray(t, dtype=pose.dtype)
    G, Gd = jax.jvp(
        lambda s: jnp.asarray(motion(s), dtype=pose.dtype), (t,), (jnp.ones_like(t),)
    )
    return G, Gd


class AbstractObstacle(eqx.Module):
    """A rigid obstacle: a signed-distance function of its own frame, placed by a pose.

    Attributes:
        pose: (4, 4) pose of the obstacle's frame in the world.
        motion: optional pure JAX function ``t -> (4, 4)`` world pose (replaces
            ``pose``; a moving obstacle drags and pushes what it touches, through
            its velocity in the damping and friction).
        name: a label for reports and plots.
    """

    pose: eqx.AbstractVar[Float[Array, "4 4"]]
    motion: eqx.AbstractVar[Hook | None]
    name: eqx.AbstractVar[str]

    def distance(self, x: Float[Array, "3"]) -> Float[Array, ""]:
        """Signed distance [m] of the point ``x`` (obstacle frame) to the surface.

        Negative inside. Its gradient is the outward unit normal.
        """
        raise NotImplementedError

    @property
    def feature_size(self) -> float:
        """The smallest radius of curvature of the surface (static, for sampling)."""
        return math.inf

    def frame(self, t) -> tuple[Array, Array]:
        """``(G, Gdot)``: world pose at time ``t`` and its rate."""
        return _motion_pose(self.motion, self.pose, t)


def _pose_field(name: str, pose) -> Array:
    if pose is None:
        return jnp.eye(4)
    check_se3(name, pose)
    with jax.ensure_compile_time_eval():
        return jnp.asarray(pose, dtype=float)


def _motion_field(name: str, motion):
    if motion is not None and not callable(motion):
        raise ValueError(
            f"{name} = {motion!r}: give a function t -> (4, 4) pose, or None."
        )
    return as_hook(motion, name)


class Plane(AbstractObstacle):
    """A half-space: the solid lies below the plane through ``point`` with ``normal``.

    A floor is ``Plane()`` (z = 0, solid below); an inclined plane tilts the normal.
    ``point`` and ``normal`` are in the obstacle frame (``pose``, default identity).

    Attributes:
        point: a point of the plane [m].
        normal: outward unit normal (normalised here).
    """

    point: Float[Array, "3"]
    normal: Float[Array, "3"]
    pose: Float[Array, "4 4"]
    motion: Hook | None
    name: str = eqx.field(static=True)

    def __init__(
        self,
        point: ArrayLike = (0.0, 0.0, 0.0),
        normal: ArrayLike = (0.0, 0.0, 1.0),
        pose: ArrayLike | None = None,
        motion: Callable | None = None,
        name: str = "plane",
    ):
        check_shape("Plane.point", point, (3,))
        check_shape("Plane.normal", normal, (3,))
        check_finite("Plane.point", point, "give a point of the plane in metres")
        check_finite("Plane.normal", normal, "give the outward normal, e.g. (0, 0, 1)")
        if is_concrete(normal) and not np.linalg.norm(np.asarray(normal, float)) > 0:
            raise ValueError(
                f"Plane.normal = {normal!r} has zero length: give the outward normal, "
                "e.g. (0, 0, 1) for a floor."
            )
        with jax.ensure_compile_time_eval():
            n = jnp.asarray(normal, dtype=float)
            self.normal = n / jnp.linalg.norm(n)
            self.point = jnp.asarray(point, dtype=float)
        self.pose = _pose_field("Plane.pose", pose)
        self.motion = _motion_field("Plane.motion", motion)
        self.name = name

    def distance(self, x):
        """Height of ``x`` above the plane."""
        return jnp.dot(x - self.point, self.normal)


class Sphere(AbstractObstacle):
    """A solid sphere.

    Attributes:
        centre: centre in the obstacle frame [m].
        radius: radius [m] > 0.
    """

    centre: Float[Array, "3"]
    radius: Float[Array, ""]
    pose: Float[Array, "4 4"]
    motion: Hook | None
    name: str = eqx.field(static=True)

    def __init__(
        self,
        radius: ArrayLike,
        centre: ArrayLike = (0.0, 0.0, 0.0),
        pose: ArrayLike | None = None,
        motion: Callable | None = None,
        name: str = "sphere",
    ):
        check_shape("Sphere.centre", centre, (3,))
        check_finite("Sphere.centre", centre, "give the centre in metres")
        self.radius = _scalar("Sphere.radius", radius, True)
        with jax.ensure_compile_time_eval():
            self.centre = jnp.asarray(centre, dtype=float)
        self.pose = _pose_field("Sphere.pose", pose)
        self.motion = _motion_field("Sphere.motion", motion)
        self.name = name

    def distance(self, x):
        """Distance to the centre minus the radius."""
        return _safe_norm(x - self.centre) - self.radius

    @property
    def feature_size(self) -> float:
        """The radius."""
        return float(self.radius) if is_concrete(self.radius) else math.inf


def closest_on_segment(x: Array, a: Array, b: Array) -> Array:
    """Parameter s in [0, 1] of the point of segment ``a b`` closest to ``x``."""
    ab = b - a
    den = jnp.dot(ab, ab)
    safe = jnp.where(den > 0, den, 1.0)
    return jnp.where(den > 0, jnp.clip(jnp.dot(x - a, ab) / safe, 0.0, 1.0), 0.0)


class Capsule(AbstractObstacle):
    """A capsule (a segment swept by a sphere): a rounded finite cylinder, a peg.

    Attributes:
        start: one end of the axis, obstacle frame [m].
        end: the other end [m].
        radius: radius [m] > 0.
    """

    start: Float[Array, "3"]
    end: Float[Array, "3"]
    radius: Float[Array, ""]
    pose: Float[Array, "4 4"]
    motion: Hook | None
    name: str = eqx.field(static=True)

    def __init__(
        self,
        radius: ArrayLike,
        start: ArrayLike = (0.0, 0.0, -1.0),
        end: ArrayLike = (0.0, 0.0, 1.0),
        pose: ArrayLike | None = None,
        motion: Callable | None = None,
        name: str = "capsule",
    ):
        check_shape("Capsule.start", start, (3,))
        check_shape("Capsule.end", end, (3,))
        for field, value in (("Capsule.start", start), ("Capsule.end", end)):
            check_finite(field, value, "give the axis' end points in metres")
        if (
            is_concrete(start)
            and is_concrete(end)
            and np.array_equal(np.asarray(start, float), np.asarray(end, float))
        ):
            raise ValueError(
                f"Capsule.start = Capsule.end = {np.asarray(start, float).tolist()}: "
                "a capsule needs an axis of nonzero length; for a ball use "
                "sj.Sphere(radius, centre)."
            )
        self.radius = _scalar("Capsule.radius", radius, True)
        with jax.ensure_compile_time_eval():
            self.start = jnp.asarray(start, dtype=float)
            self.end = jnp.asarray(end, dtype=float)
        self.pose = _pose_field("Capsule.pose", pose)
        self.motion = _motion_field("Capsule.motion", motion)
        self.name = name

    def distance(self, x):
        """Distance to the axis segment minus the radius."""
        s = closest_on_segment(x, self.start, self.end)
        return _safe_norm(x - (self.start + s * (self.end - self.start))) - self.radius

    @property
    def feature_size(self) -> float:
        """The radius."""
        return float(self.radius) if is_concrete(self.radius) else math.inf


class Box(AbstractObstacle):
    """A solid box centred at the obstacle frame's origin, edges along its axes.

    Attributes:
        half_extents: half-lengths along x, y, z [m], each > 0.
    """

    half_extents: Float[Array, "3"]
    pose: Float[Array, "4 4"]
    motion: Hook | None
    name: str = eqx.field(static=True)

    def __init__(
        self,
        half_extents: ArrayLike,
        pose: ArrayLike | None = None,
        motion: Callable | None = None,
        name: str = "box",
    ):
        check_shape("Box.half_extents", half_extents, (3,))
        _check_nonnegative("Box.half_extents", half_extents, strict=True)
        with jax.ensure_compile_time_eval():
            self.half_extents = jnp.asarray(half_extents, dtype=float)
        self.pose = _pose_field("Box.pose", pose)
        self.motion = _motion_field("Box.motion", motion)
        self.name = name

    def distance(self, x):
        """Exact signed distance of a box (outside: to the surface; inside: -depth).

        Inside, the nearest face's ``q`` is taken by its index, not by ``jnp.max``:
        the reduction's derivative averages over the entries equal to the maximum,
        and where XLA computes ``q`` in two kernels with different rounding none
        may be (0/0: a NaN tangent, seen at -O0).
        """
        q = jnp.abs(x) - self.half_extents
        outside = _safe_norm(jnp.maximum(q, 0.0))
        inside = jnp.minimum(q[jnp.argmax(q)], 0.0)
        return outside + inside


# ------------------------------------------------------------ rigid contact shapes
class AbstractContactShape(eqx.Module):
    """The contact surface of a rigid link: spheres at points of its CM frame."""

    def points(self) -> tuple[Array, Array]:
        """``(offsets (n, 3) in the CM frame [m], radii (n,) [m])``."""
        raise NotImplementedError


class ContactSphere(AbstractContactShape):
    """A sphere of ``radius`` centred at ``centre`` (CM frame; default the CM).

    Attributes:
        radius: [m] > 0.
        centre: (3,) in the CM frame [m].
    """

    radius: Float[Array, ""]
    centre: Float[Array, "3"]

    def __init__(self, radius: ArrayLike, centre: ArrayLike = (0.0, 0.0, 0.0)):
        check_shape("ContactSphere.centre", centre, (3,))
        check_finite("ContactSphere.centre", centre, "give the centre in metres")
        self.radius = _scalar("ContactSphere.radius", radius, True)
        with jax.ensure_compile_time_eval():
            self.centre = jnp.asarray(centre, dtype=float)

    def points(self):
        """One sphere."""
        return self.centre[None], self.radius[None]


class ContactCapsule(AbstractContactShape):
    """A capsule along the CM frame's x axis (a rounded cylinder), sampled by spheres.

    Attributes:
        length: length of the axis segment [m] > 0 (centred at the CM).
        radius: [m] > 0.
        n_samples: spheres along the axis (static, >= 2).
    """

    length: Float[Array, ""]
    radius: Float[Array, ""]
    n_samples: int = eqx.field(static=True)

    def __init__(
        self, length: ArrayLike, radius: ArrayLike, n_samples: int | None = None
    ):
        self.length = _scalar("ContactCapsule.length", length, True)
        self.radius = _scalar("ContactCapsule.radius", radius, True)
        if n_samples is None:
            n_samples = (
                max(2, math.ceil(float(length) / float(radius)) + 1)
                if is_concrete(self.length) and is_concrete(self.radius)
                else 8
            )
        if not isinstance(n_samples, int) or n_samples < 2:
            raise ValueError(
                f"ContactCapsule.n_samples = {n_samples!r}: give an integer >= 2."
            )
        self.n_samples = n_samples

    def points(self):
        """Spheres spaced evenly along the axis."""
        s = jnp.linspace(-0.5, 0.5, self.n_samples) * self.length
        z = jnp.zeros_like(s)
        return jnp.stack([s, z, z], axis=1), jnp.broadcast_to(self.radius, s.shape)


class ContactBox(AbstractContactShape):
    """A box centred at the CM, sampled at its corners, edge midpoints and face centres.

    The samples have zero radius: a box touches a plane, a sphere or a rod at them
    only (a sharp obstacle edge against the middle of a face is not seen).

    Attributes:
        half_extents: half-lengths along the CM frame's x, y, z [m], each > 0.
    """

    half_extents: Float[Array, "3"]

    def __init__(self, half_extents: ArrayLike):
        check_shape("ContactBox.half_extents", half_extents, (3,))
        _check_nonnegative("ContactBox.half_extents", half_extents, strict=True)
        with jax.ensure_compile_time_eval():
            self.half_extents = jnp.asarray(half_extents, dtype=float)

    def points(self):
        """26 points: 8 corners, 12 edge midpoints, 6 face centres."""
        grid = np.array(
            [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
             if (i, j, k) != (0, 0, 0)],
            dtype=float,
        )  # fmt: skip
        pts = jnp.asarray(grid) * self.half_extents[None]
        return pts, jnp.zeros(len(grid), dtype=pts.dtype)


# ------------------------------------------------------------- the contact set
class Contact(eqx.Module):
    """Which links touch what, and how: give it to ``Linkage(contact=...)``.

    Attributes:
        obstacles: tuple of obstacles (:class:`Plane`, :class:`Sphere`,
            :class:`Capsule`, :class:`Box`).
        law: the :class:`ContactLaw` (one for every contact of the scene).
        links: 1-based numbers of the links that touch the obstacles; default all
            soft links and every rigid link that has a shape.
        shapes: the rigid links' contact shapes (given as ``{link: shape}``).
        shape_links: their link numbers (static).
        radius: radii [m] overriding soft links' section extents (given as
            ``{link: radius}``).
        radius_links: their link numbers (static).
        spacing: largest distance between a soft link's samples [m]; default the
            smallest of the link's radius and the obstacles' radii of curvature
            (so that a 1 cm rod and a 1 cm sphere cannot miss each other by more
            than 7 % of the radius), with at least 4 and at most 400 cells per
            division (a given spacing is not capped).
        rod_pairs: pairs ``(a, b)`` checked against each other: two soft links
            (segment-segment closest points), or a soft link and a rigid link
            with a shape (its spheres against the rod's segments: an object in a
            gripper's fingers).
        self_contact: soft links checked against themselves (segments further apart
            along the rod than 2.5 times the sum of their radii).
        friction_in_rod_pairs: whether rod-rod contacts carry friction (default
            True; the law's coefficients).
        inside: pairs ``(tube, body)``: ``body`` (a soft link, or a rigid link
            with a shape) moves inside soft link ``tube``, whose divisions have an
            :class:`~sorojax.AnnularSection`, and touches its inner surface.
        obstacle_laws: laws of particular obstacles (given as ``{index: law}``,
            0-based into ``obstacles``: a slippery peg beside a rough floor); the
            others, the rod pairs and the tubes use ``law``.
        obstacle_law_index: their obstacle indices (static).
        tangent_in_w: whether ROS34PW2's W carries the contacts' stiffness and
            damping (obstacles, rod pairs, self-contact and tubes; default True:
            stiff contact and sticking friction then do not bound its step;
            ``benchmarks/contact.py`` measures both).
        pair_capacity: most segment pairs of one rod pair (or one rod's
            self-contact) that the narrow phase examines at once (default:
            :func:`pair_capacity` picks 4 per segment of the two rods). A broad
            phase keeps the pairs whose bounding spheres (each segment's, grown by
            its radius and the law's reach) overlap; where more overlap than
            this, the dynamics ends with ``RESULTS.contact_overflow``
            and statics says so too: raise it then. With at least as many as there
            are segment pairs, every pair is examined (no broad phase).
    """

    obstacles: tuple[AbstractObstacle, ...]
    law: ContactLaw
    links: tuple[int, ...] | None = eqx.field(static=True)
    shapes: tuple[AbstractContactShape, ...]
    shape_links: tuple[int, ...] = eqx.field(static=True)
    radius: tuple[Float[Array, ""], ...]
    radius_links: tuple[int, ...] = eqx.field(static=True)
    spacing: float | None = eqx.field(static=True)
    rod_pairs: tuple[tuple[int, int], ...] = eqx.field(static=True)
    self_contact: tuple[int, ...] = eqx.field(static=True)
    friction_in_rod_pairs: bool = eqx.field(static=True)
    inside: tuple[tuple[int, int], ...] = eqx.field(static=True)
    obstacle_laws: tuple[ContactLaw, ...]
    obstacle_law_index: tuple[int, ...] = eqx.field(static=True)
    tangent_in_w: bool = eqx.field(static=True)
    cells: tuple | None = eqx.field(static=True)  # resolved by the Linkage
    pair_capacity: int | None = eqx.field(static=True, default=None)

    def __init__(
        self,
        obstacles=(),
        law: ContactLaw | None = None,
        links=None,
        shapes=None,
        radius=None,
        spacing: float | None = None,
        rod_pairs=(),
        self_contact=(),
        friction_in_rod_pairs: bool = True,
        inside=(),
        obstacle_laws=None,
        tangent_in_w: bool = True,
        cells: tuple | None = None,
        pair_capacity: int | None = None,
    ):
        if isinstance(obstacles, AbstractObstacle):
            obstacles = (obstacles,)
        obstacles = tuple(obstacles)
        for k, ob in enumerate(obstacles):
            if not isinstance(ob, AbstractObstacle):
                raise ValueError(
                    f"Contact.obstacles[{k}] = {ob!r}: give a Plane, Sphere, Capsule "
                    "or Box."
                )
        if not isinstance(law, ContactLaw):
            raise ValueError(
                f"Contact.law = {law!r}: give a ContactLaw(stiffness=...), e.g. "
                "ContactLaw(stiffness=1e5, smoothing=1e-4)."
            )
        if spacing is not None and not (
            math.isfinite(float(spacing)) and float(spacing) > 0
        ):
            raise ValueError(
                f"Contact.spacing = {spacing!r}: give a distance > 0 [m] or None."
            )
        shapes = dict(shapes or {})
        for link, shape in shapes.items():
            if not isinstance(shape, AbstractContactShape):
                raise ValueError(
                    f"Contact.shapes[{link}] = {shape!r}: give a ContactSphere, "
                    "ContactCapsule or ContactBox."
                )
        radius = dict(radius or {})
        for link, r in radius.items():
            _check_nonnegative(f"Contact.radius[{link}]", r, strict=True)
        self.obstacles = obstacles
        self.law = law
        self.links = None if links is None else tuple(int(i) for i in links)
        # link numbers static, shapes and radii model arrays
        self.shape_links = tuple(sorted(int(k) for k in shapes))
        self.shapes = tuple(shapes[k] for k in sorted(shapes, key=int))
        self.radius_links = tuple(sorted(int(k) for k in radius))
        with jax.ensure_compile_time_eval():
            self.radius = tuple(
                jnp.asarray(radius[k], dtype=float) for k in sorted(radius, key=int)
            )
        self.spacing = None if spacing is None else float(spacing)
        self.rod_pairs = tuple((int(a), int(b)) for a, b in rod_pairs)
        self.self_contact = tuple(int(i) for i in self_contact)
        self.friction_in_rod_pairs = bool(friction_in_rod_pairs)
        self.inside = tuple((int(a), int(b)) for a, b in inside)
        obstacle_laws = dict(obstacle_laws or {})
        for k, lw in obstacle_laws.items():
            if not 0 <= int(k) < len(obstacles):
                raise ValueError(
                    f"Contact.obstacle_laws has index {k!r}: give 0-based indices "
                    f"of obstacles (0..{len(obstacles) - 1})."
                )
            if not isinstance(lw, ContactLaw):
                raise ValueError(
                    f"Contact.obstacle_laws[{k}] = {lw!r}: give a ContactLaw."
                )
        self.obstacle_law_index = tuple(sorted(int(k) for k in obstacle_laws))
        self.obstacle_laws = tuple(obstacle_laws[k] for k in sorted(obstacle_laws))
        self.tangent_in_w = bool(tangent_in_w)
        self.cells = cells
        if pair_capacity is not None and (
            isinstance(pair_capacity, bool)
            or not isinstance(pair_capacity, (int, np.integer))
            or pair_capacity < 1
        ):
            raise ValueError(
                f"Contact.pair_capacity = {pair_capacity!r}: give a whole number "
                ">= 1 of segment pairs, or None for the default (4 per segment)."
            )
        self.pair_capacity = None if pair_capacity is None else int(pair_capacity)

    def shape_of(self, link: int) -> AbstractContactShape | None:
        """The contact shape of rigid link ``link`` (None if it has none)."""
        return dict(zip(self.shape_links, self.shapes, strict=True)).get(link)

    def obstacle_law(self, k: int) -> ContactLaw:
        """The law of obstacle ``k`` (0-based): its own, or the contact's."""
        laws = dict(zip(self.obstacle_law_index, self.obstacle_laws, strict=True))
        return laws.get(k, self.law)

    def radius_of(self, link: int):
        """The radius override of soft link ``link`` (None: the section's)."""
        return dict(zip(self.radius_links, self.radius, strict=True)).get(link)


DEFAULT_TRACED_CELLS = 16  # cells per division when the lengths are traced
MIN_CELLS = 4
MAX_CELLS = 400


def _concrete_float(x) -> float | None:
    if not is_concrete(x):
        return None
    return float(np.asarray(x))


def soft_radius(contact: Contact, link_number: int, division, X1) -> Array:
    """Contact radius of a soft link at ``X1`` of ``division``: override or section."""
    r = contact.radius_of(link_number)
    if r is not None:
        return r
    ey, ez = division.section.extent(X1)
    return jnp.maximum(ey, ez)


def contact_links(contact: Contact, links) -> tuple[int, ...]:
    """The links (1-based) whose samples are checked against the obstacles."""
    from ._link import SoftLink

    if contact.links is not None:
        return contact.links
    return tuple(
        i
        for i, link in enumerate(links, start=1)
        if isinstance(link, SoftLink) or contact.shape_of(i) is not None
    )


def resolve_contact(contact: Contact, links) -> Contact:
    """Check ``contact`` against the links and fix its sample counts (``cells``).

    ``cells`` is a tuple of ``(link, (n_cells per division))`` over the soft links
    that are sampled: those touching obstacles, in rod pairs or self-contact.
    """
    from ._link import RigidLink, SoftLink

    if not isinstance(contact, Contact):
        raise ValueError(f"Linkage.contact = {contact!r}: give a sorojax.Contact.")
    n = len(links)

    def check_link(field, i, soft_only=False):
        if not 1 <= i <= n:
            raise ValueError(f"{field} = {i} is out of range: give a link in 1..{n}.")
        if soft_only and not isinstance(links[i - 1], SoftLink):
            raise ValueError(
                f"{field} = {i}: link {i} is rigid; rod-rod and self-contact are "
                "between soft links (give a rigid link a shape in Contact.shapes)."
            )

    for i in contact.links or ():
        check_link("Contact.links", i)
        if isinstance(links[i - 1], RigidLink) and contact.shape_of(i) is None:
            raise ValueError(
                f"Contact.links includes rigid link {i}, which has no contact shape: "
                f"give Contact(shapes={{{i}: ContactSphere(r)}}) (or a capsule or box)."
            )
    for i in contact.shape_links:
        check_link("Contact.shapes key", i)
        if not isinstance(links[i - 1], RigidLink):
            raise ValueError(
                f"Contact.shapes[{i}]: link {i} is soft; a soft link's surface is its "
                "section swept along the rod (override its radius with "
                "Contact(radius={...}))."
            )
    for i in contact.radius_links:
        check_link("Contact.radius key", i, soft_only=True)
    for a, b in contact.rod_pairs:
        check_link("Contact.rod_pairs entry", a)
        check_link("Contact.rod_pairs entry", b)
        for i in (a, b):
            if isinstance(links[i - 1], RigidLink) and contact.shape_of(i) is None:
                raise ValueError(
                    f"Contact.rod_pairs has rigid link {i}, which has no contact "
                    f"shape: give Contact(shapes={{{i}: ContactSphere(r)}})."
                )
        if isinstance(links[a - 1], RigidLink) and isinstance(links[b - 1], RigidLink):
            raise ValueError(
                f"Contact.rod_pairs has ({a}, {b}), two rigid links: a pair needs a "
                "soft link (rigid-rigid contact is not modelled)."
            )
        if a == b:
            raise ValueError(
                f"Contact.rod_pairs has ({a}, {b}): a link against itself is "
                f"self-contact: give Contact(self_contact=({a},))."
            )
    for i in contact.self_contact:
        check_link("Contact.self_contact entry", i, soft_only=True)
    for tube, body in contact.inside:
        check_link("Contact.inside tube", tube, soft_only=True)
        check_link("Contact.inside body", body)
        if tube == body:
            raise ValueError(
                f"Contact.inside has ({tube}, {body}): a link cannot move inside "
                "itself; give (tube, body) of two links."
            )
        for k, div in enumerate(links[tube - 1].divisions, start=1):
            if not hasattr(div.section, "inner_radius"):
                raise ValueError(
                    f"Contact.inside tube {tube}: its division {k} has a "
                    f"{type(div.section).__name__}; give the tube's divisions an "
                    "AnnularSection(outer, inner)."
                )
        if isinstance(links[body - 1], RigidLink) and contact.shape_of(body) is None:
            raise ValueError(
                f"Contact.inside body {body} is rigid and has no contact shape: give "
                f"Contact(shapes={{{body}: ContactSphere(r)}})."
            )
    sampled = set(
        i
        for i in (contact_links(contact, links) if contact.obstacles else ())
        if isinstance(links[i - 1], SoftLink)
    )
    sampled |= {
        i
        for pair in contact.rod_pairs
        for i in pair
        if isinstance(links[i - 1], SoftLink)
    }
    sampled |= set(contact.self_contact)
    sampled |= {t for t, _ in contact.inside}
    sampled |= {b for _, b in contact.inside if isinstance(links[b - 1], SoftLink)}
    features = [ob.feature_size for ob in contact.obstacles]
    given = dict(contact.cells or ())
    cells = []
    for i in sorted(sampled):
        link = links[i - 1]
        per_div = []
        for k, div in enumerate(link.divisions):
            L = _concrete_float(div.length)
            radii = [
                _concrete_float(soft_radius(contact, i, div, x))
                for x in (0.0, 0.5, 1.0)
            ]
            if L is None or any(r is None for r in radii):
                old = given.get(i)
                per_div.append(
                    old[k] if old is not None and len(old) > k else DEFAULT_TRACED_CELLS
                )
                continue
            n_cells = max(MIN_CELLS, math.ceil(L / (contact.spacing or 1.0) - 1e-9))
            if contact.spacing is None:  # the default: capped at MAX_CELLS
                h = min([min(radii), *features])  # type: ignore[type-var]
                n_cells = min(MAX_CELLS, max(MIN_CELLS, math.ceil(L / h - 1e-9)))
            per_div.append(int(n_cells))
        cells.append((i, tuple(per_div)))
    return Contact(
        contact.obstacles,
        contact.law,
        links=contact.links,
        shapes=dict(zip(contact.shape_links, contact.shapes, strict=True)),
        radius=dict(zip(contact.radius_links, contact.radius, strict=True)),
        spacing=contact.spacing,
        rod_pairs=contact.rod_pairs,
        self_contact=contact.self_contact,
        friction_in_rod_pairs=contact.friction_in_rod_pairs,
        inside=contact.inside,
        obstacle_laws=dict(
            zip(contact.obstacle_law_index, contact.obstacle_laws, strict=True)
        ),
        tangent_in_w=contact.tangent_in_w,
        cells=tuple(cells),
        pair_capacity=contact.pair_capacity,
    )


PAIRS_PER_SEGMENT = 4  # default broad-phase capacity per segment of a rod pair


def pair_capacity(contact: Contact, n_pairs: int, n_segments: int) -> int:
    """Segment pairs the narrow phase examines for one rod pair (static).

    ``n_pairs``: the pair's segment pairs; ``n_segments``: its two rods' segments
    (one rod's, for self-contact). At most ``n_pairs`` (then there is no broad
    phase).
    """
    k = contact.pair_capacity
    if k is None:
        k = PAIRS_PER_SEGMENT * n_segments
    return min(int(k), int(n_pairs))
