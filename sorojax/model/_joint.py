"""Lumped joints at the base of every link: N, R, P, H, U, C, A, S, F.

A joint's basis ``Phi_j`` (6 x n) has one column per free direction (angular first);
its pose is ``exp(Phi_j q_j)`` (DESIGN.md section 3). Axes are chosen by the user:

- ``R`` revolute about ``axis``; ``P`` prismatic along ``axis``; ``H`` helical about
  and along ``axis`` with ``pitch`` [m/rad]; ``C`` cylindrical (rotation + translation
  about/along ``axis``);
- ``U`` universal: the two rotations perpendicular to ``axis`` (default x: rotations
  about y and z, the manual's "constrained about x");
- ``A`` planar: rotation about the plane normal ``axis`` and the two translations in
  the plane (default normal z: the x-y plane);
- ``S`` spherical (three rotations), ``F`` free (six), ``N`` fixed (none).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._checks import check_positive

JOINT_TYPES = {
    "N": "fixed",
    "R": "revolute",
    "P": "prismatic",
    "H": "helical",
    "U": "universal",
    "C": "cylindrical",
    "A": "planar",
    "S": "spherical",
    "F": "free",
}
JOINT_DOFS = {"N": 0, "R": 1, "P": 1, "H": 1, "U": 2, "C": 2, "A": 3, "S": 3, "F": 6}
_DEFAULT_AXIS = {"A": (0.0, 0.0, 1.0)}


def perpendicular_pair(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``a`` to a right-handed orthonormal frame.

    For a coordinate axis e_i this is (e_{i+1}, e_{i+2}) cyclically, so that the
    default universal joint frees rotations about y and z.
    """
    a = np.asarray(a, dtype=float)
    for i in range(3):
        e = np.zeros(3)
        e[i] = 1.0
        if np.allclose(a, e):
            u = np.zeros(3)
            u[(i + 1) % 3] = 1.0
            v = np.zeros(3)
            v[(i + 2) % 3] = 1.0
            return u, v
    ref = np.eye(3)[int(np.argmin(np.abs(a)))]
    u = np.cross(a, ref)
    u /= np.linalg.norm(u)
    v = np.cross(a, u)
    return u, v


class Joint(eqx.Module):
    """A lumped joint.

    The joint's type and axis are stored as its free directions, arrays (like every
    physical parameter): programs compiled for one joint serve every joint with as
    many freedoms, so a revolute about z and a prismatic along x, or two revolutes
    about different axes, share compiled programs; only the number of freedoms is
    part of a model's structure. ``kind`` and ``axis`` are read back from the
    directions (outside traced code).

    Attributes:
        directions: ``(6, n)`` free directions at zero pitch, angular rows first
            (unit columns; ``basis()`` adds ``pitch * lead``).
        lead: ``(6, n)`` the translation per unit pitch (the helical joint's axis;
            zero for every other type).
        pitch: helical pitch [m/rad] (used by ``H`` only).
        stiffness: joint stiffness matrix ``(n, n)`` [N m/rad or N/m].
        damping: joint damping matrix ``(n, n)``.
    """

    directions: Float[Array, "6 n"]
    lead: Float[Array, "6 n"]
    pitch: Float[Array, ""]
    stiffness: Float[Array, "n n"]
    damping: Float[Array, "n n"]

    def __init__(
        self,
        kind: str = "N",
        axis=None,
        *,
        pitch: ArrayLike = 0.0,
        stiffness: ArrayLike = 0.0,
        damping: ArrayLike = 0.0,
    ):
        """Build a joint.

        Args:
            kind: one letter of ``N R P H U C A S F`` (see the module text).
            axis: the joint's axis in its frame (normalised); default x (z for
                ``A``). ``S``, ``F`` and ``N`` have none.
            pitch: helical pitch [m/rad] (``H``).
            stiffness: scalar, ``(n,)`` or ``(n, n)`` [N m/rad or N/m].
            damping: scalar, ``(n,)`` or ``(n, n)``.

        Raises:
            ValueError: unknown kind, a zero or non-finite axis, bad stiffness or
                damping shapes or negative values.
        """
        if not isinstance(kind, str) or kind.upper() not in JOINT_TYPES:
            raise ValueError(
                f"Joint.kind = {kind!r} is not a joint type: use one of "
                + ", ".join(f"'{k}' ({v})" for k, v in JOINT_TYPES.items())
                + "."
            )
        kind = kind.upper()
        if axis is None:
            axis = _DEFAULT_AXIS.get(kind, (1.0, 0.0, 0.0))
        a = np.asarray(axis, dtype=float)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-12:
            raise ValueError(
                f"Joint.axis = {axis!r} is not allowed: give a non-zero 3-vector."
            )
        norm = np.linalg.norm(a)
        if abs(norm - 1.0) > 4 * np.finfo(float).eps:  # a unit axis is kept exactly
            a = a / norm
        if not _traced(pitch) and not np.all(np.isfinite(np.asarray(pitch, float))):
            raise ValueError(
                f"Joint.pitch = {pitch!r} is not finite: give the helical pitch in "
                "m/rad (0 for a pure rotation)."
            )
        n = JOINT_DOFS[kind]
        directions, lead = _directions(kind, a)
        # numpy -> a transfer, no operation to compile; concrete even when the joint
        # is built under jit (kind and axis are read back from them)
        with jax.ensure_compile_time_eval():
            self.directions = jnp.asarray(directions)
            self.lead = jnp.asarray(lead)
            self.pitch = (  # traced if given traced
                jnp.asarray(pitch, dtype=float)
                if _traced(pitch)
                else jnp.asarray(np.asarray(pitch, dtype=float))
            )
        self.stiffness = _as_matrix("Joint.stiffness", stiffness, n)
        self.damping = _as_matrix("Joint.damping", damping, n)

    @property
    def n_dof(self) -> int:
        """Number of joint coordinates."""
        return self.directions.shape[-1]  # (models stacked for vmap: ..., 6, n)

    @property
    def kind(self) -> str:
        """The joint type (a letter of ``N R P H U C A S F``), from the directions."""
        return _classify(*self._concrete("kind"))[0]

    @property
    def axis(self) -> tuple[float, float, float]:
        """The unit axis, read from the directions (x for ``N``, ``S`` and ``F``)."""
        return _classify(*self._concrete("axis"))[1]

    def _concrete(self, what: str) -> tuple[np.ndarray, np.ndarray]:
        try:
            with jax.ensure_compile_time_eval():
                return np.asarray(self.directions), np.asarray(self.lead)
        except (
            jax.errors.ConcretizationTypeError,
            jax.errors.TracerArrayConversionError,
        ) as err:
            raise ValueError(
                f"Joint.{what} is read from the joint's directions, which are traced "
                "here (inside jit, grad or vmap): read it outside traced code, or use "
                "Joint.basis()."
            ) from err

    def basis(self) -> Float[Array, "6 n"]:
        """The joint basis ``Phi_j`` (6 x n_dof), angular rows first."""
        parts = (self.directions, self.pitch, self.lead)
        if any(_traced(x) for x in parts):
            return self.directions + self.pitch * self.lead
        # concrete (a model being built): on the host, no operation to compile
        d, p, lead = (np.asarray(x) for x in parts)
        return jnp.asarray(d + p * lead)


def _traced(x) -> bool:
    return any(isinstance(v, jax.core.Tracer) for v in jax.tree.leaves(x))


def _directions(kind: str, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(directions, lead)`` (6 x n each) of a joint type about/along ``a``."""
    z3 = np.zeros(3)

    def rot(v):
        return np.concatenate([v, z3])

    def tra(v):
        return np.concatenate([z3, v])

    n = JOINT_DOFS[kind]
    lead = np.zeros((6, n))
    if kind == "N":
        return np.zeros((6, 0)), lead
    if kind in ("R", "H"):
        cols = [rot(a)]
        if kind == "H":
            lead = tra(a)[:, None]
    elif kind == "P":
        cols = [tra(a)]
    elif kind == "U":
        u, v = perpendicular_pair(a)
        cols = [rot(u), rot(v)]
    elif kind == "C":
        cols = [rot(a), tra(a)]
    elif kind == "A":
        u, v = perpendicular_pair(a)
        cols = [rot(a), tra(u), tra(v)]
    elif kind == "S":
        cols = [rot(e) for e in np.eye(3)]
    else:  # "F"
        cols = list(np.eye(6))
    return np.stack(cols, axis=1), lead


def _classify(directions: np.ndarray, lead: np.ndarray) -> tuple[str, tuple]:
    """``(kind, axis)`` from a joint's directions (inverse of :func:`_directions`)."""
    n = directions.shape[1]
    x_axis = (1.0, 0.0, 0.0)
    if n == 0:
        return "N", x_axis
    if n == 6:
        return "F", x_axis
    angular = [bool(np.any(directions[:3, k])) for k in range(n)]
    first = directions[:3, 0] if angular[0] else directions[3:, 0]
    axis = tuple(float(x) for x in first)
    if n == 1:
        if np.any(lead):
            return "H", axis
        return ("R" if angular[0] else "P"), axis
    if n == 2:
        if all(angular):  # U: the rotations perpendicular to its axis
            return "U", tuple(
                float(x) for x in np.cross(directions[:3, 0], directions[:3, 1])
            )
        return "C", axis
    if all(angular):
        return "S", x_axis
    return "A", axis


def _as_matrix(field: str, value, n: int) -> Array:
    # numpy for concrete values: a transfer at the end, no operation to compile
    xp = jnp if _traced(value) else np
    arr = xp.asarray(value, dtype=float)
    if arr.ndim == 0:
        check_positive(field, value, allow_zero=True)
        return jnp.asarray(arr * xp.eye(n))
    if arr.shape == (n,):
        check_positive(field, value, allow_zero=True)
        return jnp.asarray(xp.diag(arr))
    if arr.shape == (n, n):
        return jnp.asarray(arr)
    raise ValueError(
        f"{field} has shape {arr.shape}: give a scalar, a ({n},) vector or an "
        f"({n}, {n}) matrix for this {n}-DoF joint."
    )
