"""Build-time validation helpers: clear ``ValueError`` naming the field and the fix.

Checks run only on concrete values; inside ``jit``/``grad`` traces the values are
abstract and are checked where they were built instead.
"""

import math

import jax
import numpy as np


def is_concrete(x) -> bool:
    """True when ``x`` holds a concrete value (not a JAX tracer)."""
    return not isinstance(x, jax.core.Tracer)


def check_positive(field: str, value, *, allow_zero: bool = False) -> None:
    """Raise ``ValueError`` if a concrete ``value`` is not (strictly) positive."""
    if not is_concrete(value) or callable(value):
        return
    arr = np.asarray(value, dtype=float)
    bad = ~np.isfinite(arr) | ((arr < 0) if allow_zero else (arr <= 0))
    if np.any(bad):
        allowed = "a finite value >= 0" if allow_zero else "a finite value > 0"
        raise ValueError(f"{field} = {value!r} is not allowed: give {allowed}.")


def check_finite(field: str, value, fix: str = "give finite numbers") -> None:
    """Raise ``ValueError`` if a concrete ``value`` holds a NaN or an infinity."""
    if value is None or not is_concrete(value) or callable(value):
        return
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        shown = arr.tolist() if arr.size <= 8 else "an array with non-finite entries"
        raise ValueError(f"{field} = {shown} is not finite: {fix}.")


def check_tolerances(rtol, atol, defaults: str, never: str) -> None:
    """Raise ``ValueError`` unless concrete tolerances are finite, >= 0, not both 0.

    ``defaults`` names the defaults in the message (e.g. ``"default 1e-10"``),
    ``never`` what both at 0 would mean (e.g. ``"Newton can never stop"``).
    """
    for name, value in (("rtol", rtol), ("atol", atol)):
        if is_concrete(value) and not 0 <= float(value) < math.inf:
            raise ValueError(
                f"{name} = {value!r}: give a finite tolerance >= 0 ({defaults})."
            )
    if is_concrete(rtol) and is_concrete(atol) and float(rtol) + float(atol) == 0:
        raise ValueError(f"rtol = atol = 0: {never}; give either > 0.")


def check_shape(field: str, value, shape: tuple[int, ...]) -> None:
    """Raise ``ValueError`` if ``value`` does not have exactly ``shape``."""
    got = np.shape(value)
    if got != shape:
        raise ValueError(
            f"{field} has shape {got}, expected {shape}: "
            f"give an array of shape {shape}."
        )


def check_se3(field: str, value) -> None:
    """Raise ``ValueError`` unless ``value`` is a 4x4 homogeneous transform."""
    check_shape(field, value, (4, 4))
    if not is_concrete(value):
        return
    g = np.asarray(value, dtype=float)
    R = g[:3, :3]
    if (
        not np.allclose(g[3], [0, 0, 0, 1], atol=1e-9)
        or not np.allclose(R.T @ R, np.eye(3), atol=1e-6)
        or np.linalg.det(R) < 0
    ):
        raise ValueError(
            f"{field} is not an SE(3) pose: give [[R, p], [0, 0, 0, 1]] with R a "
            "rotation matrix (orthonormal, det +1)."
        )
