"""One process of tests/test_learn_processes.py: two steps of the learning example.

Usage: python _learn_worker.py PROCESS_ID N_PROCESSES PORT OUT.npz

``examples/learn_reach.py``'s data-parallel Adam step (``make_train_step``) on a
fixed batch of 8 targets (the whole pool, in the order the step's key draws),
episodes of 4 control periods; with 2 processes each differentiates 4 targets.
Saves the loss of each step, the weights and Adam's state after each step, and a
``sorojax.process_sum`` of leaves of three dtypes.
"""

import importlib.util
import pathlib
import sys

import sorojax as sj

pid, n_proc, port, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4]
if n_proc > 1:  # before any JAX computation (the example's import makes none)
    sj.initialize_processes(f"localhost:{port}", n_proc, pid)

path = pathlib.Path(__file__).resolve().parent.parent / "examples" / "learn_reach.py"
spec = importlib.util.spec_from_file_location("learn_reach", path)
ex = importlib.util.module_from_spec(spec)
spec.loader.exec_module(ex)  # sets jax_enable_x64

import equinox as eqx  # noqa: E402
import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
import optax  # noqa: E402

env = ex.make_env()
s0 = env.reset(jax.random.key(0))
params, static = eqx.partition(
    ex.Policy(env.linkage.n_dof, jax.random.key(1)), eqx.is_array
)
# 8 targets around the hanging tip (lateral offsets up to 0.1 m)
offsets = np.random.default_rng(0).uniform(-0.1, 0.1, (8, 3)) * [1.0, 1.0, 0.2]
pool = jnp.asarray(np.asarray(env.tip_position(s0)) + offsets)
optimiser = optax.adam(3e-3)
opt_state = optimiser.init(params)
step = ex.make_train_step(env, s0, static, optimiser, pool, batch=8, periods=4)
saved = {"processes": np.asarray(jax.process_count())}
# process_sum of leaves of three dtypes (one gather each), process-dependent values
mixed = sj.process_sum(
    {
        "i": (pid + 1) * jnp.arange(3, dtype=jnp.int32),
        "f": jnp.full((2, 2), 0.5 * (pid + 1)),
        "h": jnp.float32(pid + 1),
    }
)
for name, leaf in mixed.items():
    saved[f"mixed_{name}"] = np.asarray(leaf)
with jax.numpy_dtype_promotion("standard"):  # optax's Adam relies on it
    for k, key in enumerate(jax.random.split(jax.random.key(7), 2)):
        params, opt_state, loss = step(params, opt_state, key)
        saved[f"loss_{k}"] = np.asarray(loss)
        for name, tree in (("params", params), ("opt", opt_state)):
            for i, leaf in enumerate(jax.tree.leaves(tree)):
                saved[f"{name}_{k}_{i}"] = np.asarray(leaf)
np.savez(out, **saved)
