"""Coordinates of a soft link that best reproduce a given strain field."""

from collections.abc import Callable

import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike

from .._jit import jit
from ..model._link import SoftLink
from ..model._linkage import Linkage
from ..model._precompute import precompute


def strain_coordinates(
    linkage: Linkage,
    strain: ArrayLike | Callable[[Array], ArrayLike],
    link: int = 1,
    q: ArrayLike | None = None,
) -> Array:
    """``q`` whose strain on soft link ``link`` best fits ``strain`` (least squares).

    Used to set initial and reference-relative configurations, e.g. a rod pre-bent at
    1 rad/m about y: ``strain_coordinates(rod, [0, 1, 0, 0, 0, 0])``. The fit is by
    Gauss quadrature over every division, so a strain the basis can represent is
    reproduced exactly; modes the basis lacks are ignored.

    Args:
        linkage: the model.
        strain: the screw strain ``(kx, ky, kz, gx, gy, gz)`` [1/m, -], a constant or a
            function of the arc length ``s`` [m] from the link's start; the link's
            reference strain is subtracted (``q`` measures the deviation from it).
        link: 1-based index of a soft link.
        q: coordinates to start from (other links keep theirs); default zeros.

    Returns:
        ``(n_dof,)`` coordinates.
    """
    soft = [i + 1 for i, lk in enumerate(linkage.links) if isinstance(lk, SoftLink)]
    if not 1 <= link <= linkage.n_links or not isinstance(
        linkage.links[link - 1], SoftLink
    ):
        raise ValueError(
            f"link = {link} is not a soft link of this linkage (links are 1-based; "
            f"soft links: {soft})."
        )
    q = None if q is None else jnp.asarray(q, dtype=float)
    return _fit(linkage, strain if callable(strain) else jnp.asarray(strain), link, q)


@jit
def _fit(linkage: Linkage, strain, link: int, q) -> Array:
    """The fit of :func:`strain_coordinates`, one compiled program.

    Run eagerly, its few dozen small operations were compiled one by one (87
    programs, 2.5 s on 2 cores for the free-fall rod's initial shape; now 0.5 s).
    """
    fn = strain if callable(strain) else (lambda s: strain)
    data = precompute(linkage)
    lay = linkage.layout.links[link - 1]
    q = jnp.zeros(linkage.n_dof) if q is None else q
    s0 = 0.0
    for dd, dl, div in zip(
        data.links[link - 1].divisions,
        lay.divisions,
        linkage.links[link - 1].divisions,
        strict=True,
    ):
        L = div.length
        w = jnp.asarray(dl.w) * L
        s = s0 + jnp.asarray(dl.X1) * L
        target = jax.vmap(lambda x: jnp.asarray(fn(x), dtype=float))(s)
        if target.shape != (len(dl.X1), 6):
            raise ValueError(
                f"strain gives shape {target.shape[1:]}; expected (6,) "
                "(kx, ky, kz, gx, gy, gz)."
            )
        target = target - dd.xi_ref
        A = jnp.einsum("p,pai,paj->ij", w, dd.Phi, dd.Phi)
        if dd.locked is not None:  # padding (zero columns) fits to zero
            A = A + jnp.diag(dd.locked)
        b = jnp.einsum("p,pai,pa->i", w, dd.Phi, target)
        if dd.n_dof:
            q = q.at[dd.offset : dd.offset + dd.n_dof].set(jnp.linalg.solve(A, b))
        s0 = s0 + L
    return q
