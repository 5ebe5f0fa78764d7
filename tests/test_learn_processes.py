"""Data-parallel learning: examples/learn_reach.py's training step over two local
CPU processes (jax.distributed, gloo; one device each) equals the one-process step."""

import os
import pathlib
import socket
import subprocess
import sys

import jax
import numpy as np
import pytest

WORKER = pathlib.Path(__file__).with_name("_learn_worker.py")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


@pytest.mark.slow  # three worker processes, each compiling the training step (~30 s)
def test_two_process_learning_step_equals_one_process(tmp_path):
    """Two Adam steps on a batch of 8 targets (4-period episodes of the four-cable
    arm), split 4 + 4 over two processes whose losses and gradients are summed by
    sorojax.process_sum, against the same steps on the whole batch in one process:
    the loss, every weight and Adam's moments (which hold the gradient itself: the
    first moment is 0.1 g after one step, whereas Adam's update alone hides a
    wrong gradient scale) agree to 1e-10 in float64 (the two runs differ only in
    the order of the batch sums, ~1e-16 relative), and both processes hold the same
    weights. Also sorojax.process_sum on leaves of three dtypes."""
    port = str(_free_port())
    # one CPU device per process; the suite's other XLA flags (LLVM -O0: half the
    # compile) and its persistent compilation cache apply to the workers too
    flags = os.environ.get("XLA_FLAGS", "").split()
    env = {
        **os.environ,
        "JAX_PLATFORMS": "cpu",
        "XLA_FLAGS": " ".join(f for f in flags if "device_count" not in f),
        "JAX_COMPILATION_CACHE_DIR": str(jax.config.jax_compilation_cache_dir or ""),
        "JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS": "0.5",
    }
    runs = [(1, 0), (2, 0), (2, 1)]  # (processes, id): all three at once
    procs = [
        subprocess.Popen(
            [sys.executable, str(WORKER), str(p), str(n), port,
             str(tmp_path / f"out{n}_{p}.npz")],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )
        for n, p in runs
    ]  # fmt: skip
    for proc in procs:
        log, _ = proc.communicate(timeout=600)
        assert proc.returncode == 0, log[-3000:]
    one, *two = (np.load(tmp_path / f"out{n}_{p}.npz") for n, p in runs)
    assert int(one["processes"]) == 1 and int(two[0]["processes"]) == 2
    # process_sum: in one process its argument, over two the sum 1 x + 2 x, each
    # leaf's dtype kept (exact: small integers and halves)
    for out, factor in ((one, 1), *((o, 3) for o in two)):
        np.testing.assert_array_equal(out["mixed_i"], factor * np.arange(3))
        np.testing.assert_array_equal(out["mixed_f"], np.full((2, 2), 0.5 * factor))
        assert float(out["mixed_h"]) == factor
        assert [out[f"mixed_{k}"].dtype for k in "ifh"] == [
            "int32",
            "float64",
            "float32",
        ]
    keys = [k for k in one.files if not k.startswith(("processes", "mixed"))]
    assert {"loss_0", "loss_1", "params_1_0", "opt_1_0"} <= set(keys)
    for out in two:
        assert sorted(out.files) == sorted(one.files)
        for k in keys:
            diff = np.max(np.abs(out[k] - one[k]), initial=0.0)
            assert diff <= 1e-10, f"{k}: 2 processes vs 1 differ by {diff:.2e}"
    for k in keys:  # every process applies the same update
        np.testing.assert_array_equal(two[0][k], two[1][k], err_msg=k)
    assert float(one["loss_0"]) > 0
