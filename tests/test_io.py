"""Trajectory files: exact .npz round trip, SoRoSim-style .mat, overwrite protection."""

import pathlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.io

import sorojax
from sorojax.io import load_trajectory, save_trajectory

N_SAVE, N_DOF = 5, 7
FIELDS = ("t", "q", "qd", "num_steps", "num_accepted_steps", "num_rejected_steps")


def _trajectory(result=sorojax.RESULTS.successful, batch=()):
    """A hand-built Trajectory (no simulation: nothing to compile)."""
    rng = np.random.default_rng(0)
    t = jnp.broadcast_to(jnp.linspace(0.0, 0.1, N_SAVE), (*batch, N_SAVE))
    q = jnp.asarray(rng.standard_normal((*batch, N_SAVE, N_DOF)))
    qd = jnp.asarray(rng.standard_normal((*batch, N_SAVE, N_DOF)))
    return sorojax.Trajectory(
        t=t,
        q=q,
        qd=qd,
        result=result,
        num_steps=jnp.full(batch, 17),
        num_accepted_steps=jnp.full(batch, 12),
        num_rejected_steps=jnp.full(batch, 5),
    )


@pytest.fixture(scope="module")
def traj():
    return _trajectory()


def _assert_same(a, b):
    for name in FIELDS:
        x, y = np.asarray(getattr(a, name)), np.asarray(getattr(b, name))
        assert x.dtype == y.dtype and x.shape == y.shape, name
        np.testing.assert_array_equal(x, y, err_msg=name)
    assert bool(jnp.all(a.result == b.result)), "result"


@pytest.mark.parametrize("as_str", [False, True])
def test_npz_round_trip_is_exact(tmp_path, traj, as_str):
    path = tmp_path / "traj.npz"
    written = save_trajectory(str(path) if as_str else path, traj)
    assert written == path and path.is_file()
    loaded = load_trajectory(str(path) if as_str else path)
    assert isinstance(loaded, sorojax.Trajectory)
    _assert_same(loaded, traj)


def test_npz_keeps_failure_code_and_batches(tmp_path):
    # A vmapped batch whose members failed differently: the codes survive per member.
    result = jax.vmap(
        lambda p: sorojax.RESULTS.where(
            p, sorojax.RESULTS.max_steps_reached, sorojax.RESULTS.nonlinear_divergence
        )
    )(jnp.asarray([True, False]))
    traj = _trajectory(result=result, batch=(2,))
    save_trajectory(tmp_path / "batch.NPZ", traj)
    loaded = load_trajectory(tmp_path / "batch.NPZ")
    _assert_same(loaded, traj)
    codes = np.asarray(loaded.result._value)
    assert codes.shape == (2,) and codes[0] != codes[1], "per-member result codes"


def test_mat_has_sorosim_variables(tmp_path, traj):
    path = save_trajectory(tmp_path / "DynamicsSolution.mat", traj)
    mat = scipy.io.loadmat(path)
    assert mat["t"].shape == (N_SAVE, 1), "t must be a column, as SoRoSim writes it"
    assert mat["qqd"].shape == (N_SAVE, 2 * N_DOF)
    np.testing.assert_array_equal(mat["t"][:, 0], np.asarray(traj.t))
    np.testing.assert_array_equal(mat["qqd"], np.asarray(traj.qqd))


def test_mat_round_trip(tmp_path, traj):
    path = save_trajectory(tmp_path / "traj.mat", traj)
    loaded = load_trajectory(path)
    # float64 written as MATLAB doubles: exact, 1e-15 allows for any re-encoding.
    for name in ("t", "q", "qd"):
        np.testing.assert_allclose(
            getattr(loaded, name), getattr(traj, name), rtol=0, atol=1e-15, err_msg=name
        )
    assert bool(loaded.result == sorojax.RESULTS.successful)
    for name in ("num_steps", "num_accepted_steps", "num_rejected_steps"):
        assert int(getattr(loaded, name)) == -1, f"{name}: unknown in a .mat file"


def test_mat_written_by_matlab_is_read(tmp_path):
    # SoRoSim's file: t column, qqd, plus other variables we ignore; a failed
    # integration's inf rows make the result `failed`.
    t = np.linspace(0, 1, 4)[:, None]
    qqd = np.arange(24.0).reshape(4, 6)
    qqd[-1] = np.inf
    scipy.io.savemat(tmp_path / "sorosim.mat", {"t": t, "qqd": qqd, "u": np.ones(3)})
    loaded = load_trajectory(tmp_path / "sorosim.mat")
    assert loaded.q.shape == (4, 3) and loaded.qd.shape == (4, 3)
    np.testing.assert_array_equal(loaded.qqd[:3], qqd[:3])
    assert bool(loaded.result == sorojax.RESULTS.failed)


def test_mat_rejects_missing_variable_and_batches(tmp_path):
    scipy.io.savemat(tmp_path / "bad.mat", {"t": np.zeros((3, 1))})
    with pytest.raises(ValueError, match="qqd"):
        load_trajectory(tmp_path / "bad.mat")
    with pytest.raises(ValueError, match="npz"):
        save_trajectory(tmp_path / "batch.mat", _trajectory(batch=(2,)))
    assert not (tmp_path / "batch.mat").exists()


@pytest.mark.parametrize("suffix", [".npz", ".mat"])
def test_existing_file_is_not_overwritten(tmp_path, traj, suffix):
    path = tmp_path / f"traj{suffix}"
    path.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="overwrite=True") as err:
        save_trajectory(path, traj)
    assert str(path) in str(err.value)
    assert path.read_bytes() == b"precious", "the old content must stay intact"
    save_trajectory(path, traj, overwrite=True)
    np.testing.assert_array_equal(load_trajectory(path).q, traj.q)
    assert sorted(p.name for p in tmp_path.iterdir()) == [path.name], "temp files left"


def test_unknown_suffix(tmp_path, traj):
    with pytest.raises(ValueError, match=r"'\.csv'.*\.npz, \.mat"):
        save_trajectory(tmp_path / "traj.csv", traj)
    assert not list(tmp_path.iterdir())
    (tmp_path / "traj.h5").write_bytes(b"")
    with pytest.raises(ValueError, match=r"'\.h5'"):
        load_trajectory(tmp_path / "traj.h5")


def test_load_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.npz"):
        load_trajectory(tmp_path / "missing.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(ValueError, match="lacks the arrays"):
        load_trajectory(tmp_path / "other.npz")
    with pytest.raises(TypeError, match="Trajectory"):
        save_trajectory(tmp_path / "x.npz", {"t": np.zeros(3)})
    with pytest.raises(FileNotFoundError, match="does not exist"):
        save_trajectory(pathlib.Path(tmp_path, "no", "dir.npz"), _trajectory())


def test_works_with_jax_tree_tools(tmp_path, traj):
    # A loaded trajectory is an ordinary pytree of the same structure.
    save_trajectory(tmp_path / "t.npz", traj)
    loaded = load_trajectory(tmp_path / "t.npz")
    assert jax.tree.structure(loaded) == jax.tree.structure(traj)
