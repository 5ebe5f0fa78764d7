"""Closed-loop joints: a lumped joint between two link tips (or a tip and the ground).

Frame A = tip of link A times ``g_A``; frame B = tip of link B (or the world, for
``link_B = 0``) times ``g_B``. The joint lets ``g_B^-1 g_A`` move along the joint's
free directions only; the other directions are constrained (the manual's CLj with
gACLj, gBCLj). Constraint errors are ``Phi_p^T log(g_B^-1 g_A)`` with ``Phi_p`` the
complement of the joint's free directions (DESIGN.md section 2); for the universal
joint, whose free rotations do not compose to a rotation vector in their span, the
exact error ``(u^T R v, p)`` is used instead (``u, v`` its free axes).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from ._checks import check_se3
from ._joint import Joint


class ClosedLoopJoint(eqx.Module):
    """A joint closing a loop between the tips of links A and B.

    Attributes:
        joint: the joint type and axis (a :class:`~sorojax.Joint`; its stiffness and
            damping are not used), or a letter of ``N R P H U C A S F``.
        link_A: 1-based link number of A.
        link_B: 1-based link number of B, or 0 for the ground.
        g_A: pose of the joint frame in A's tip frame.
        g_B: pose of the joint frame in B's tip frame (world pose for ground).
        kind: the joint's type letter and ``axis`` its axis, kept static: the
            constraint rows' formula depends on them (a universal joint's, a
            helical joint's), where a link's joint is only its directions.
    """

    joint: Joint
    link_A: int = eqx.field(static=True)
    link_B: int = eqx.field(static=True)
    g_A: Float[Array, "4 4"]
    g_B: Float[Array, "4 4"]
    basis_p: tuple[tuple[float, ...], ...] = eqx.field(static=True)
    kind: str = eqx.field(static=True)
    axis: tuple[float, float, float] = eqx.field(static=True)

    def __init__(
        self,
        joint: Joint | str,
        link_A: int,
        link_B: int = 0,
        g_A: ArrayLike | None = None,
        g_B: ArrayLike | None = None,
    ):
        if isinstance(joint, str):
            joint = Joint(joint)
        if not isinstance(joint, Joint):
            raise ValueError(
                f"ClosedLoopJoint.joint = {joint!r}: give a Joint or a joint letter."
            )
        kind = joint.kind  # raises under jit: the rows are fixed at build time
        if kind == "F":
            raise ValueError(
                "ClosedLoopJoint.joint is free ('F'): it constrains nothing; leave it "
                "out."
            )
        for name, g in (("g_A", g_A), ("g_B", g_B)):
            if g is not None:
                check_se3(f"ClosedLoopJoint.{name}", g)
        self.joint = joint
        self.link_A = int(link_A)
        self.link_B = int(link_B)
        eye = np.eye(4)  # a transfer, not an operation to compile
        self.g_A = jnp.asarray(eye if g_A is None else g_A, dtype=float)
        self.g_B = jnp.asarray(eye if g_B is None else g_B, dtype=float)
        self.basis_p = tuple(map(tuple, _complement(joint).tolist()))
        self.kind = kind
        self.axis = joint.axis

    @property
    def n_constraints(self) -> int:
        """Number of constraint rows: 6 minus the joint's freedoms."""
        return 6 - self.joint.n_dof

    def constrained_basis(self) -> np.ndarray:
        """``Phi_p`` (6 x n_constraints): orthonormal complement of the free axes.

        Computed when the joint is built (a helical pitch is read then).
        """
        return np.asarray(self.basis_p, dtype=float).reshape(6, self.n_constraints)


def _complement(joint: Joint) -> np.ndarray:
    try:
        with jax.ensure_compile_time_eval():  # concrete even when built under jit
            Phi = np.asarray(joint.basis(), dtype=float)
    except jax.errors.ConcretizationTypeError as err:  # a traced helical pitch
        raise ValueError(
            "ClosedLoopJoint.joint: a helical closure needs a concrete pitch (its "
            "constrained directions are fixed when the model is built); build the "
            "ClosedLoopJoint outside jit/grad."
        ) from err
    # Gram-Schmidt of the unit directions against the free ones: for axis-aligned
    # joints the rows are plain components (e.g. wx, wy, vx, vy, vz for R about z).
    Q = _orthonormal(Phi.T)
    rows: list = []
    for e in np.eye(6):
        v = e - sum(((e @ b) * b for b in Q + rows), np.zeros(6))
        if np.linalg.norm(v) > 1e-6:
            rows.append(v / np.linalg.norm(v))
    return np.stack(rows, axis=1)


def _orthonormal(vectors) -> list:
    out: list = []
    for v in vectors:
        w = v - sum(((v @ b) * b for b in out), np.zeros(len(v)))
        if np.linalg.norm(w) > 1e-12:
            out.append(w / np.linalg.norm(w))
    return out
