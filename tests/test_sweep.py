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


class _Killed(Exception):
    pass


def test_checkpointed_sweep_resumes_with_only_the_missing_blocks(tmp_path):
    """A sweep killed after two of its three blocks (five statics cases, two per
    block) and run again computes only the third block. Its results equal an
    uninterrupted checkpointed sweep's exactly (the same compiled programs per
    block) and a plain sweep's to rounding (1e-14 m: the plain one runs the five
    cases as one program); a third run computes nothing."""
    P = jnp.linspace(0.1, 2.0, 5)
    plain = sj.sweep(_tip_y, P, chunk=2)
    ref = sj.sweep(_tip_y, P, chunk=2, checkpoint=tmp_path / "whole", block=2)
    np.testing.assert_allclose(np.asarray(ref[0]), np.asarray(plain[0]), atol=1e-14)
    folder = tmp_path / "sweep"
    seen = []

    def kill_after_two(b, n_blocks, computed):
        seen.append((b, n_blocks, computed))
        if b == 1:
            raise _Killed

    with pytest.raises(_Killed):
        sj.sweep(
            _tip_y, P, chunk=2, checkpoint=folder, block=2, progress=kill_after_two
        )
    assert seen == [(0, 3, True), (1, 3, True)]
    assert sorted(p.name for p in folder.iterdir()) == [
        "block_000000.npz",
        "block_000001.npz",
        "sweep.json",
    ]
    seen.clear()
    tips, codes = sj.sweep(
        _tip_y, P, chunk=2, checkpoint=folder, block=2,
        progress=lambda *a: seen.append(a),
    )  # fmt: skip
    assert seen == [(0, 3, False), (1, 3, False), (2, 3, True)]
    np.testing.assert_array_equal(np.asarray(tips), np.asarray(ref[0]))
    np.testing.assert_array_equal(np.asarray(codes), np.asarray(ref[1]))
    seen.clear()
    again = sj.sweep(
        _tip_y, P, chunk=2, checkpoint=folder, block=2,
        progress=lambda *a: seen.append(a),
    )  # fmt: skip
    assert [c for *_, c in seen] == [False, False, False]
    np.testing.assert_array_equal(np.asarray(again[0]), np.asarray(ref[0]))


def test_checkpoint_of_another_sweep_is_refused_and_left_unchanged(tmp_path):
    folder = tmp_path / "sweep"
    sj.sweep(jnp.sin, jnp.arange(4.0), checkpoint=folder, block=2)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    with pytest.raises(ValueError, match="inputs_sha256.*new folder"):
        sj.sweep(jnp.sin, jnp.arange(4.0) + 1, checkpoint=folder, block=2)
    with pytest.raises(ValueError, match="block"):
        sj.sweep(jnp.sin, jnp.arange(4.0), checkpoint=folder, block=3)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    with pytest.raises(ValueError, match="checkpoint=FOLDER"):
        sj.sweep(jnp.sin, jnp.arange(4.0), block=2)
