"""Coordinates of a soft link that best reproduce a given strain field."""

import warnings
from collections.abc import Callable

import equinox as eqx
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
    *,
    total: bool = False,
) -> Array:
    """``q`` whose strain on soft link ``link`` best fits ``strain`` (least squares).

    Used to set initial configurations. By default ``strain`` is the deviation from
    the link's reference strain (what ``q`` measures), so a straight rod pre-bent at
    1 rad/m about y, keeping its reference stretch, is
    ``strain_coordinates(rod, [0, 1, 0, 0, 0, 0])``; the same in total strain is
    ``strain_coordinates(rod, [0, 1, 0, 1, 0, 0], total=True)`` (the straight
    reference's elongation 1 included). The fit is by Gauss quadrature over every
    division, so a strain the basis can represent is reproduced exactly; modes the
    basis lacks keep their reference value, and asking a nonzero deviation of one
    of them is warned of, naming it (the fit drops it).

    Args:
        linkage: the model.
        strain: the screw strain ``(kx, ky, kz, gx, gy, gz)`` [1/m, -], a constant or a
            function of the arc length ``s`` [m] from the link's start: the deviation
            from the reference strain, or with ``total=True`` the whole strain.
        link: 1-based index of a soft link.
        q: coordinates to start from (other links keep theirs); default zeros.
        total: ``strain`` includes the reference strain (the fit subtracts it).

    Returns:
        ``(n_dof,)`` coordinates.

    Warns:
        UserWarning: ``strain`` asks a nonzero value of a component that a division
            of the link has no mode for (named in the message; the fit drops it).

    Raises:
        ValueError: ``link`` is not a soft link; ``strain`` is not a 6-vector; or the
            fitted axial stretch ``gx`` (reference included) is <= 0 somewhere on the
            link, i.e. the rod would collapse or turn inside out (typically a total
            strain without its elongation 1 passed as a deviation, or a deviation
            with ``total=True``). Under an outer ``jax.jit``/``vmap``/``grad`` the
            last check runs inside the program (``equinox.error_if``).
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
    if not callable(strain):
        strain = jnp.asarray(strain)
        if strain.shape != (6,):
            raise ValueError(
                f"strain gives shape {strain.shape}; expected (6,) "
                "(kx, ky, kz, gx, gy, gz), or a function of the arc length s."
            )
    q, gx_min, s_min, dropped = _fit(linkage, strain, link, q, bool(total))
    kind = "total strain" if total else "deviation from the reference strain"
    _warn_dropped(dropped, link, kind)
    fix = (
        "pass the deviation from the reference (the default, e.g. "
        "[0, 1, 0, 0, 0, 0] bends at 1 rad/m and keeps the reference stretch), or "
        "with total=True include the elongation (e.g. [0, 1, 0, 1, 0, 0])"
    )
    if isinstance(gx_min, jax.core.Tracer):
        return eqx.error_if(
            q,
            gx_min <= 0,
            f"strain_coordinates: strain (a {kind}) gives link {link} an axial "
            f"stretch gx <= 0, collapsing or inverting the rod; {fix}.",
        )
    if not float(gx_min) > 0:
        raise ValueError(
            f"strain (a {kind}) gives link {link} an axial stretch gx = "
            f"{float(gx_min):.6g} (reference included) at s = {float(s_min):.4g} m: "
            f"a rod with gx <= 0 collapses or turns inside out; {fix}."
        )
    return q


_COMPONENTS = (
    "torsion kx", "bending ky", "bending kz", "elongation gx", "shear gy", "shear gz"
)  # fmt: skip


def _warn_dropped(dropped, link: int, kind: str) -> None:
    """Warn of a strain on components that no division of the link can carry.

    A warning, not an error: fitting a measured or tabulated strain field (a
    centre line's curvatures) to a model that leaves modes out on purpose is a
    least-squares fit by design. Under an outer trace nothing is checked.
    """
    if isinstance(dropped, jax.core.Tracer):
        return
    d = jax.device_get(dropped)
    names = [f"{_COMPONENTS[a]} = {float(d[a]):.6g}" for a in range(6) if d[a] > 0]
    if names:
        warnings.warn(
            f"strain_coordinates: the strain (a {kind}) asks for components that "
            f"link {link}'s strain basis does not carry, and the fit drops them: "
            f"{', '.join(names)} (largest asked). Give 0 for them, or add their "
            "modes to the link's basis (e.g. LegendreBasis((1, 1, 1, 0, 0, 0), "
            "order) for torsion and both bendings).",
            stacklevel=3,
        )


@jit
def _fit(linkage: Linkage, strain, link: int, q, total: bool):
    """The fit of :func:`strain_coordinates`, one compiled program.

    Returns ``(q, gx_min, s_min, dropped)``: the coordinates, the smallest fitted
    axial stretch on the link (reference included), the arc length [m] where it is,
    and per strain component the largest |asked value| in a division whose basis has
    no column for that component (``(6,)``, zero when nothing is dropped).
    """
    fn = strain if callable(strain) else (lambda s: strain)
    data = precompute(linkage)
    lay = linkage.layout.links[link - 1]
    q = jnp.zeros(linkage.n_dof) if q is None else q
    s0 = 0.0
    gx, ss = [], []
    dropped = jnp.zeros(6)
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
        if total:
            target = target - dd.xi_ref
        absent = jnp.all(dd.Phi == 0, axis=(0, 2))  # (6,): no column carries it
        asked = jnp.max(jnp.abs(target), axis=0)
        dropped = jnp.maximum(dropped, jnp.where(absent, asked, 0.0))
        A = jnp.einsum("p,pai,paj->ij", w, dd.Phi, dd.Phi)
        if dd.locked is not None:  # padding (zero columns) fits to zero
            A = A + jnp.diag(dd.locked)
        b = jnp.einsum("p,pai,pa->i", w, dd.Phi, target)
        if dd.n_dof:
            q_div = jnp.linalg.solve(A, b)
            q = q.at[dd.offset : dd.offset + dd.n_dof].set(q_div)
            gx.append(dd.Phi[:, 3, :] @ q_div + dd.xi_ref[:, 3])
        else:
            gx.append(dd.xi_ref[:, 3])
        ss.append(s)
        s0 = s0 + L
    gx, ss = jnp.concatenate(gx), jnp.concatenate(ss)
    i = jnp.argmin(gx)
    return q, gx[i], ss[i], dropped
