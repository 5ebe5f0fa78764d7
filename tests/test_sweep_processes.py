"""sorojax.sweep across processes: two local CPU processes joined by
jax.distributed (gloo) sweep the same cases as one process."""

import os
import pathlib
import socket
import subprocess
import sys

import numpy as np
import pytest

WORKER = pathlib.Path(__file__).with_name("_sweep_worker.py")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def _launch(n_proc, tmp_path, *case):
    port = str(_free_port())
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    env.pop("XLA_FLAGS", None)  # one CPU device per process
    procs = [
        subprocess.Popen(
            [sys.executable, str(WORKER), str(p), str(n_proc), port,
             str(tmp_path / f"out{n_proc}_{p}.npz"), *case],
            env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )
        for p in range(n_proc)
    ]  # fmt: skip
    for proc in procs:
        log, _ = proc.communicate(timeout=300)
        assert proc.returncode == 0, log[-3000:]
    return [np.load(tmp_path / f"out{n_proc}_{p}.npz") for p in range(n_proc)]


def test_two_processes_sweep_as_one(tmp_path):
    """Seven cantilever statics over two processes (4 + 3 cases, the short share
    padded): every process gathers all seven tips, equal to a single-process sweep
    to 1e-12 m; with gather=False each keeps its own rows, and the two ranges cover
    every case once."""
    (one,) = _launch(1, tmp_path)
    two = _launch(2, tmp_path)
    assert int(one["processes"]) == 1 and int(two[0]["processes"]) == 2
    for out in two:
        np.testing.assert_allclose(out["tips"], one["tips"], rtol=0, atol=1e-12)
        assert np.all(out["codes"] == 0)
    ranges = [tuple(out["range"]) for out in two]
    assert ranges == [(0, 4), (4, 7)]
    mine = np.concatenate([out["mine"] for out in two])
    np.testing.assert_allclose(mine, one["tips"], rtol=0, atol=1e-12)
    assert np.all(np.diff(one["tips"]) > 0)  # more load, more deflection


@pytest.mark.slow  # three more launches (~25 s of CPU); the cantilever's split is default
def test_two_processes_sweep_the_cable_arm_as_one(tmp_path):
    """256 statics of the four-cable arm (random tensions up to 10 N) over two
    processes: the gathered tips equal a single-process sweep's to 1e-12 m, every
    case converged, and the two processes' ranges cover every case once."""
    (one,) = _launch(1, tmp_path, "arm")
    two = _launch(2, tmp_path, "arm")
    assert one["tips"].shape == (256, 3) and np.all(one["codes"] == 0)
    for out in two:
        np.testing.assert_allclose(out["tips"], one["tips"], rtol=0, atol=1e-12)
    assert [tuple(out["range"]) for out in two] == [(0, 128), (128, 256)]
    mine = np.concatenate([out["mine"] for out in two])
    np.testing.assert_allclose(mine, one["tips"], rtol=0, atol=1e-12)


@pytest.mark.slow  # two more launches (~20 s of CPU); one process's resume is default
def test_two_processes_checkpoint_and_resume(tmp_path):
    """A checkpointed sweep over two processes: each process saves its own share
    (4 + 3 cantilever cases, blocks of 2) in its own subfolder; rerun after each
    process lost its last block file, each computes that block only (counted) and
    the gathered tips equal a plain single-process sweep's to 1e-12 m."""
    (one,) = _launch(1, tmp_path)
    two = _launch(2, tmp_path, str(tmp_path / "ckpt"))
    assert sorted(p.name for p in (tmp_path / "ckpt").iterdir()) == [
        "process_0_of_2",
        "process_1_of_2",
    ]
    for out in two:
        for run in (1, 2):
            np.testing.assert_allclose(
                out[f"tips_{run}"], one["tips"], rtol=0, atol=1e-12
            )
        assert out["computed_1"].tolist() == [True, True]  # 2 blocks of each share
        assert out["computed_2"].tolist() == [False, True]  # only the lost one
