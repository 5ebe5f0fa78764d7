"""jaxtyping aliases shared across sorojax.

Every 6-vector in sorojax (twist, strain, wrench) is **angular first**:
``xi = (kx, ky, kz, gx, gy, gz)`` = (torsion, bend about y, bend about z, elongation,
shear y, shear z); a wrench is ``(moment, force)``. Poses are 4x4 SE(3) matrices.
"""

from jaxtyping import Array, ArrayLike, Float

Twist = Float[Array, "6"]
Strain = Float[Array, "6"]
Wrench = Float[Array, "6"]
SE3 = Float[Array, "4 4"]
Scalar = Float[ArrayLike, ""]

__all__ = ["Array", "ArrayLike", "Float", "SE3", "Scalar", "Strain", "Twist", "Wrench"]
