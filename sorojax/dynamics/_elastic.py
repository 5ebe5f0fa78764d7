"""Generalised stiffness K and damping D (the manual's findK and findD).

Both are constant and assembled once by :func:`sorojax.model.precompute`:
K = sum_p w_p Phi_p^T Sigma_p Phi_p + joint stiffness, D likewise with Upsilon.
"""

from jaxtyping import Array, Float

from .._jit import jit
from ..model._linkage import Linkage
from ..model._precompute import precompute


@jit
def stiffness_matrix(linkage: Linkage) -> Float[Array, "n_dof n_dof"]:
    """Generalised stiffness matrix K (symmetric, constant)."""
    return precompute(linkage).K


@jit
def damping_matrix(linkage: Linkage) -> Float[Array, "n_dof n_dof"]:
    """Generalised damping matrix D (symmetric, constant)."""
    return precompute(linkage).D
