"""sorojax.sweep: the vmapped function, sharded and chunked, case for case."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import sorojax as sj
from sorojax.scenes import cantilever


def _tip_y(P):
    rod = cantilever(
        1.0,
        0.01,
        1e7,
        modes=(0, 0, 1, 0, 0, 0),
        order=2,
        tip_wrench=jnp.stack([0.0, 0.0, 0.0, 0.0, P, 0.0]),
    )
    sol = sj.solve_statics(rod, throw=False)
    return sj.tip_pose(rod, sol.q)[1, 3], sol.result._value


@pytest.mark.parametrize("chunk", [None, 2, "auto"])
def test_sweep_equals_vmap_and_drops_the_padding(chunk):
    """Five loads (chunk 2: padded to 6 with a copy of the last case; "auto": at
    most 8 per chunk on CPU): the same tips as jax.vmap of the same solve, to
    rounding (1e-14 m), in input order."""
    P = jnp.linspace(0.1, 2.0, 5)
    tips, codes = sj.sweep(_tip_y, P, chunk=chunk)
    ref, ref_codes = jax.jit(jax.vmap(_tip_y))(P)
    assert np.asarray(tips).shape == (5,)
    np.testing.assert_allclose(np.asarray(tips), np.asarray(ref), rtol=0, atol=1e-14)
    assert np.all(np.asarray(codes) == 0) and np.all(np.asarray(ref_codes) == 0)
    assert np.all(np.diff(np.asarray(tips)) > 0)  # more load, more deflection


def test_sweep_rejects_mismatched_batches():
    with pytest.raises(ValueError, match="leading axes"):
        sj.sweep(lambda a, b: a + b, jnp.ones(3), jnp.ones(4))
    with pytest.raises(ValueError, match="chunk"):
        sj.sweep(lambda a: a, jnp.ones(3), chunk=0)
    with pytest.raises(ValueError, match="'auto'"):
        sj.sweep(lambda a: a, jnp.ones(3), chunk="big")
