"""Checkpointed training (examples/learn_reach.py's ``train``): an interrupted run,
resumed, ends where an uninterrupted one does, computing only the missing steps."""

import json

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
from test_examples import _load  # one loader for the example scripts


def test_resumed_training_equals_uninterrupted(tmp_path):
    """Six Adam steps (batches of 4 of 8 targets, 2-period episodes of the
    four-cable arm): a run stopped after 3 steps and resumed from its checkpoint
    computes the 3 missing steps only and ends with the weights, Adam's state and
    the losses of an uninterrupted run, bit for bit (the same compiled step on
    the same saved float64 arrays); a finished run resumed computes nothing; a
    folder of another run is refused and left unchanged."""
    ex = _load("learn_reach")
    env = ex.make_env()
    s0 = env.reset(jax.random.key(0))
    policy = ex.Policy(env.linkage.n_dof, jax.random.key(1), width=16)
    params, static = eqx.partition(policy, eqx.is_array)
    offsets = np.random.default_rng(0).uniform(-0.1, 0.1, (8, 3)) * [1.0, 1.0, 0.2]
    pool = jnp.asarray(np.asarray(env.tip_position(s0)) + offsets)
    optimiser = optax.adam(1e-2)
    opt_state = optimiser.init(params)
    step = ex.make_train_step(env, s0, static, optimiser, pool, batch=4, periods=2)
    keys = jax.random.split(jax.random.key(3), 6)
    run = {"iterations": 6, "batch": 4, "lr": 1e-2, "seed": 3}
    folder = tmp_path / "run"
    with jax.numpy_dtype_promotion("standard"):  # optax's Adam relies on it
        ref = ex.train(step, params, opt_state, keys)
        first = ex.train(
            step, params, opt_state, keys, folder, run, every=2, max_steps=3
        )
        saved = dict(np.load(folder / "state.npz"))
        resumed = ex.train(step, params, opt_state, keys, folder, run, every=2)
        again = ex.train(step, params, opt_state, keys, folder, run, every=2)
    assert (ref[3], first[3], resumed[3], again[3]) == (6, 3, 3, 0)
    assert int(saved["step"]) == 3 and len(saved["losses"]) == 3
    assert json.loads((folder / "run.json").read_text())["run"] == run
    for out in (resumed, again):
        for a, b in zip(
            jax.tree.leaves(out[:2]), jax.tree.leaves(ref[:2]), strict=True
        ):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))
        assert out[2] == ref[2]  # the six losses
    moved = [np.abs(a - b).max() for a, b in zip(
        jax.tree.leaves(ref[0]), jax.tree.leaves(params), strict=True)]  # fmt: skip
    assert min(moved) > 1e-4  # every weight array was trained (Adam steps ~1e-2)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    other = {**run, "lr": 2e-2}
    with pytest.raises(ValueError, match=f"{folder}.*another run.*delete"):
        ex.train(step, params, opt_state, keys, folder, other)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
