"""Material of a soft link: Young's modulus, Poisson ratio, density, damping."""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float

from ._checks import check_positive


class Material(eqx.Module):
    """Linear elastic, Kelvin-Voigt damped material.

    Attributes:
        E: Young's modulus [Pa], > 0.
        poisson: Poisson ratio [-], in (-1, 0.5]; shear modulus G = E / (2 (1 + nu)).
        rho: density [kg/m^3], >= 0.
        eta: Kelvin-Voigt material damping [Pa s], >= 0.
    """

    E: Float[Array, ""]
    poisson: Float[Array, ""]
    rho: Float[Array, ""]
    eta: Float[Array, ""]

    def __init__(
        self,
        E: ArrayLike,
        poisson: ArrayLike = 0.5,
        rho: ArrayLike = 1000.0,
        eta: ArrayLike = 0.0,
    ):
        check_positive("Material.E", E)
        check_positive("Material.rho", rho, allow_zero=True)
        check_positive("Material.eta", eta, allow_zero=True)
        try:
            nu = float(poisson)
        except Exception:  # traced: checked where built
            nu = 0.0
        if not (-1.0 < nu <= 0.5):
            raise ValueError(
                f"Material.poisson = {poisson!r} is not allowed: give a value in "
                "(-1, 0.5]."
            )
        self.E = jnp.asarray(E, dtype=float)
        self.poisson = jnp.asarray(poisson, dtype=float)
        self.rho = jnp.asarray(rho, dtype=float)
        self.eta = jnp.asarray(eta, dtype=float)

    @property
    def G(self) -> Float[Array, ""]:
        """Shear modulus [Pa]."""
        return self.E / (2.0 * (1.0 + self.poisson))
