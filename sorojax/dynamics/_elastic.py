"""Generalised stiffness K and damping D (the manual's findK and findD).

Both are constant and assembled once by :func:`sorojax.model.precompute`:
K = sum_p w_p Phi_p^T Sigma_p Phi_p + joint stiffness, D likewise with Upsilon.
"""

import equinox as eqx
from jaxtyping import Array, Float

from ..model._linkage import Linkage
from ..model._precompute import precompute


@eqx.filter_jit
def stiffness_matrix(linkage: Linkage) -> Float[Array, "n_dof n_dof"]:
    """Generalised stiffness matrix K (symmetric, constant)."""
    return precompute(linkage).K


@eqx.filter_jit
def damping_matrix(linkage: Linkage) -> Float[Array, "n_dof n_dof"]:
    """Generalised damping matrix D (symmetric, constant)."""
    return precompute(linkage).D
