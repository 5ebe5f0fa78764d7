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

    Attributes:
        kind: one letter of ``N R P H U C A S F``.
        axis: unit axis (tuple of 3 floats) in the joint frame; see the module text.
        pitch: helical pitch [m/rad] (used by ``H`` only).
        stiffness: joint stiffness matrix ``(n, n)`` [N m/rad or N/m].
        damping: joint damping matrix ``(n, n)``.
    """

    kind: str = eqx.field(static=True)
    axis: tuple[float, float, float] = eqx.field(static=True)
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
        a = a / np.linalg.norm(a)
        n = JOINT_DOFS[kind]
        self.kind = kind
        self.axis = (float(a[0]), float(a[1]), float(a[2]))
        self.pitch = jnp.asarray(pitch, dtype=float)
        self.stiffness = _as_matrix("Joint.stiffness", stiffness, n)
        self.damping = _as_matrix("Joint.damping", damping, n)

    @property
    def n_dof(self) -> int:
        """Number of joint coordinates."""
        return JOINT_DOFS[self.kind]

    def basis(self) -> Float[Array, "6 n"]:
        """The joint basis ``Phi_j`` (6 x n_dof), angular rows first."""
        a = np.asarray(self.axis)
        z3 = np.zeros(3)

        def rot(v):
            return np.concatenate([v, z3])

        def tra(v):
            return np.concatenate([z3, v])

        k = self.kind
        if k == "N":
            return jnp.zeros((6, 0))
        if k == "R":
            cols = [rot(a)]
        elif k == "P":
            cols = [tra(a)]
        elif k == "H":
            return (
                jnp.asarray(rot(a))[:, None] + self.pitch * jnp.asarray(tra(a))[:, None]
            )
        elif k == "U":
            u, v = perpendicular_pair(a)
            cols = [rot(u), rot(v)]
        elif k == "C":
            cols = [rot(a), tra(a)]
        elif k == "A":
            u, v = perpendicular_pair(a)
            cols = [rot(a), tra(u), tra(v)]
        elif k == "S":
            cols = [rot(e) for e in np.eye(3)]
        else:  # "F"
            cols = list(np.eye(6))
        return jnp.asarray(np.stack(cols, axis=1))


def _as_matrix(field: str, value, n: int) -> Array:
    # numpy for concrete values: a transfer at the end, no operation to compile
    traced = any(isinstance(v, jax.core.Tracer) for v in jax.tree.leaves(value))
    xp = jnp if traced else np
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
