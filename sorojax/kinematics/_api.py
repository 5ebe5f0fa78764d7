"""Public kinematics queries on a :class:`~sorojax.model.Linkage`.

The manual's FwdKinematics, Jacobian, Jacobiandot, ScrewStrain and ScrewVelocity. Each
function precomputes the linkage's derived arrays and runs the recursion of
:mod:`sorojax.kinematics._recursion`; all are ``eqx.filter_jit``-ed, so repeated calls
on models of the same structure reuse one compilation, and all vmap over ``q``.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._jit import jit
from ..model._linkage import Linkage
from ..model._precompute import precompute
from ._recursion import jacobians_dot, poses, poses_and_jacobians, strains


class Kinematics(eqx.Module):
    """Kinematic state at every significant point (see ``Linkage.layout``).

    Attributes:
        g: (n_points, 4, 4) poses in the world frame.
        J: (n_points, 6, n_dof) body Jacobians (angular rows first).
        xi: (n_points, 6) screw strains.
        eta: (n_points, 6) body twists ``J qd``.
        Jdot: (n_points, 6, n_dof) time derivatives of the Jacobians.
    """

    g: Float[Array, "n_points 4 4"]
    J: Float[Array, "n_points 6 n_dof"]
    xi: Float[Array, "n_points 6"]
    eta: Float[Array, "n_points 6"]
    Jdot: Float[Array, "n_points 6 n_dof"]


def _as_q(linkage: Linkage, q, name="q") -> Array:
    q = jnp.asarray(q)
    if not jnp.issubdtype(q.dtype, jnp.floating):
        q = q.astype(float)
    if q.shape != (linkage.n_dof,):
        raise ValueError(
            f"{name} has shape {q.shape}; this linkage has n_dof = {linkage.n_dof}: "
            f"give an array of shape ({linkage.n_dof},)."
        )
    return q


@jit
def forward_kinematics(linkage: Linkage, q: ArrayLike) -> Float[Array, "n_points 4 4"]:
    """Poses of all significant points (the manual's ``FwdKinematics``).

    Args:
        linkage: the model.
        q: coordinates, shape ``(n_dof,)``.

    Returns:
        ``(n_points, 4, 4)`` world poses.

    Raises:
        ValueError: ``q`` of the wrong shape.
    """
    q = _as_q(linkage, q)
    return poses(precompute(linkage), q)


@jit
def jacobians(linkage: Linkage, q: ArrayLike) -> Float[Array, "n_points 6 n_dof"]:
    """Body Jacobians of all significant points (the manual's ``Jacobian``)."""
    q = _as_q(linkage, q)
    return poses_and_jacobians(precompute(linkage), q)[1]


@jit
def jacobians_time_derivative(
    linkage: Linkage, q: ArrayLike, qd: ArrayLike
) -> Float[Array, "n_points 6 n_dof"]:
    """dJ/dt at all significant points (the manual's ``Jacobiandot``)."""
    q = _as_q(linkage, q)
    qd = _as_q(linkage, qd, "qd")
    return jacobians_dot(precompute(linkage), q, qd)


@jit
def screw_strains(linkage: Linkage, q: ArrayLike) -> Float[Array, "n_points 6"]:
    """Screw strains at all significant points (the manual's ``ScrewStrain``)."""
    q = _as_q(linkage, q)
    return strains(precompute(linkage), q)


@jit
def screw_velocities(
    linkage: Linkage, q: ArrayLike, qd: ArrayLike
) -> Float[Array, "n_points 6"]:
    """Body twists ``J qd`` at all points (the manual's ``ScrewVelocity``)."""
    q = _as_q(linkage, q)
    qd = _as_q(linkage, qd, "qd")
    J = poses_and_jacobians(precompute(linkage), q)[1]
    return J @ qd


@jit
def kinematics(
    linkage: Linkage, q: ArrayLike, qd: ArrayLike | None = None
) -> Kinematics:
    """All kinematic quantities at once (one recursion; Jdot by forward mode)."""
    q = _as_q(linkage, q)
    qd = jnp.zeros_like(q) if qd is None else _as_q(linkage, qd, "qd")
    data = precompute(linkage)
    g, J = poses_and_jacobians(data, q)
    return Kinematics(
        g=g, J=J, xi=strains(data, q), eta=J @ qd, Jdot=jacobians_dot(data, q, qd)
    )


def tip_pose(linkage: Linkage, q: ArrayLike, link: int = -1) -> Float[Array, "4 4"]:
    """World pose of the tip reference point of link ``link`` (1-based; -1 = last).

    One compiled program per model structure serves every link (the poses of all
    points, :func:`forward_kinematics`, indexed outside it).
    """
    link = linkage.n_links if link == -1 else link
    idx = linkage.tip_point(link)
    g = forward_kinematics(linkage, q)
    if isinstance(g, jax.core.Tracer):
        return g[idx]
    # indexing a concrete array compiles a program per shape: take it on the host
    return jnp.asarray(np.asarray(g)[idx])
