"""Saving and loading :class:`~sorojax.Trajectory` results (``.npz`` and ``.mat``).

Two formats, chosen by the file suffix:

- ``.npz`` (NumPy archive): the exact trajectory. Arrays ``t``, ``q``, ``qd``, the
  result code as an index ``result`` plus the list of code names ``result_names``
  (so that a file stays readable if codes are added), the step counters
  ``num_steps``, ``num_accepted_steps``, ``num_rejected_steps``,
  ``format_version``, and for actuated or closed-loop models ``u``, ``efforts`` and
  ``lam``. Loading gives back the same values, dtypes and shapes (batched,
  vmapped trajectories included). No pickles are written or read.
- ``.mat`` (MATLAB, SoRoSim's ``DynamicsSolution.mat``): ``t`` as an
  ``(n_save, 1)`` column [s] and ``qqd = [q, qd]`` as ``(n_save, 2 n_dof)``. Only the
  states are stored: loading a ``.mat`` file gives step counters of -1 (unknown) and a
  result of ``RESULTS.successful`` (``RESULTS.failed`` if some state is not finite,
  as after a failed integration). scipy is imported only for ``.mat`` files.

Not traced: these functions convert to NumPy and must run outside ``jit``.
"""

import os
import pathlib

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from .._results import RESULTS
from ..integrate._trajectory import Trajectory
from ._files import as_path, writing

SUFFIXES = (".npz", ".mat")
"""File suffixes understood by :func:`save_trajectory` and :func:`load_trajectory`."""

FORMAT_VERSION = 1
"""Version of the ``.npz`` layout written by :func:`save_trajectory`."""

_COUNTERS = ("num_steps", "num_accepted_steps", "num_rejected_steps")
_OPTIONAL = ("u", "efforts", "lam")  # actuated / constrained runs only
# eqx.Enumeration has no public way to list its items or to read/set an item's index:
# the private ``_name_to_item`` (names in definition order) and ``_value`` are used
# here only; test_io's round trips catch a change in equinox.
_RESULT_NAMES = tuple(RESULTS._name_to_item)


def _suffix(path: pathlib.Path) -> str:
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ValueError(
            f"{str(path)!r} has the suffix {path.suffix!r}, which is not a trajectory "
            f"format: use one of {', '.join(SUFFIXES)} (.npz: exact round trip; "
            ".mat: SoRoSim's t and qqd)."
        )
    return suffix


def _result_index(result) -> np.ndarray:
    return np.asarray(result._value, dtype=np.int32)


def _result_from_index(index: np.ndarray, names) -> RESULTS:
    """The ``RESULTS`` item of stored indices (any shape) into stored code names.

    Going through the names keeps old files right if codes are added or reordered.
    """
    index = np.asarray(index)
    if np.any((index < 0) | (index >= len(names))):
        raise ValueError(
            f"result indices {np.unique(index).tolist()} are out of range for the "
            f"{len(names)} stored result names: the file is damaged."
        )
    used = {names[i] for i in np.unique(index)}
    unknown = sorted(used - set(_RESULT_NAMES))
    if unknown:
        raise ValueError(
            f"the file's result codes {unknown} are not sorojax.RESULTS codes of this "
            f"version ({', '.join(_RESULT_NAMES)}): it was written by a newer "
            "sorojax; load it with that version."
        )
    current = np.asarray(
        [_result_index(RESULTS._name_to_item.get(n, RESULTS.failed)) for n in names],
        dtype=np.int32,
    )
    # eqx.Enumeration.where only takes a scalar predicate; a batch (vmapped) result
    # is an item whose value is an index array, built directly.
    return eqx.tree_at(
        lambda r: r._value, RESULTS.successful, np.asarray(current[index])
    )


# ------------------------------------------------------------------------------ npz
def _save_npz(file: pathlib.Path, traj: Trajectory) -> None:
    arrays = {
        "format_version": np.asarray(FORMAT_VERSION),
        "t": np.asarray(traj.t),
        "q": np.asarray(traj.q),
        "qd": np.asarray(traj.qd),
        "result": _result_index(traj.result),
        "result_names": np.asarray(_RESULT_NAMES),
    }
    for name in _COUNTERS:
        arrays[name] = np.asarray(getattr(traj, name))
    for name in _OPTIONAL:
        if getattr(traj, name) is not None:
            arrays[name] = np.asarray(getattr(traj, name))
    with open(file, "wb") as f:
        np.savez(f, **arrays)


def _load_npz(path: pathlib.Path) -> Trajectory:
    try:
        archive = np.load(path, allow_pickle=False)
    except (ValueError, OSError) as err:
        raise ValueError(
            f"{str(path)!r} is not a readable .npz archive ({err}): was it written "
            "by sorojax.io.save_trajectory?"
        ) from err
    with archive:
        needed = ("t", "q", "qd", "result", "result_names", *_COUNTERS)
        missing = [k for k in needed if k not in archive.files]
        if missing:
            raise ValueError(
                f"{str(path)!r} lacks the arrays {missing} (it has "
                f"{sorted(archive.files)}): it is not a trajectory written by "
                "sorojax.io.save_trajectory."
            )
        version = int(archive["format_version"]) if "format_version" in archive else 1
        if version > FORMAT_VERSION:
            raise ValueError(
                f"{str(path)!r} has format_version {version}; this sorojax reads "
                f"up to {FORMAT_VERSION}: upgrade sorojax to load it."
            )
        data = {k: archive[k] for k in needed}
        optional = {k: jnp.asarray(archive[k]) for k in _OPTIONAL if k in archive}
    result = _result_from_index(data["result"], data["result_names"].tolist())
    return Trajectory(
        t=jnp.asarray(data["t"]),
        q=jnp.asarray(data["q"]),
        qd=jnp.asarray(data["qd"]),
        result=result,
        **{k: jnp.asarray(data[k]) for k in _COUNTERS},
        **optional,
    )


# ------------------------------------------------------------------------------ mat
def _save_mat(file: pathlib.Path, traj: Trajectory) -> None:
    import scipy.io

    t, q, qd = np.asarray(traj.t), np.asarray(traj.q), np.asarray(traj.qd)
    if t.ndim != 1 or q.ndim != 2 or qd.shape != q.shape or q.shape[0] != t.shape[0]:
        raise ValueError(
            f"a .mat file holds one trajectory (t (n_save,), q and qd (n_save, "
            f"n_dof)); got t {t.shape}, q {q.shape}, qd {qd.shape}. For a batch "
            "(vmapped) trajectory save the whole batch as .npz, or save each member "
            "`jax.tree.map(lambda x: x[i], traj)` on its own."
        )
    qqd = np.concatenate([q, qd], axis=1)
    with open(file, "wb") as f:
        scipy.io.savemat(f, {"t": t.reshape(-1, 1), "qqd": qqd}, oned_as="column")


def _load_mat(path: pathlib.Path) -> Trajectory:
    import scipy.io

    try:
        mat = scipy.io.loadmat(path)
    except NotImplementedError as err:
        raise ValueError(
            f"{str(path)!r} is a MATLAB v7.3 (HDF5) file, which scipy cannot read: "
            "save it again in MATLAB with save(..., '-v7'), or read it with h5py."
        ) from err
    except ValueError as err:
        raise ValueError(
            f"{str(path)!r} is not a readable MATLAB file ({err})."
        ) from err
    missing = [k for k in ("t", "qqd") if k not in mat]
    if missing:
        found = sorted(k for k in mat if not k.startswith("__"))
        raise ValueError(
            f"{str(path)!r} lacks the variables {missing} (it has {found}): a "
            "trajectory .mat file holds SoRoSim's t (n_save x 1) and qqd "
            "(n_save x 2 ndof)."
        )
    t = np.asarray(mat["t"], dtype=float).reshape(-1)
    qqd = np.asarray(mat["qqd"], dtype=float)
    if qqd.ndim != 2 or qqd.shape[0] != t.shape[0] or qqd.shape[1] % 2:
        raise ValueError(
            f"{str(path)!r}: qqd has shape {qqd.shape} and t {len(t)} entries; "
            "expected qqd of shape (len(t), 2 ndof), one row [q, qd] per time."
        )
    n = qqd.shape[1] // 2
    finite = bool(np.all(np.isfinite(qqd)))
    unknown = jnp.asarray(-1, dtype=jnp.int32)
    return Trajectory(
        t=jnp.asarray(t),
        q=jnp.asarray(qqd[:, :n]),
        qd=jnp.asarray(qqd[:, n:]),
        result=RESULTS.successful if finite else RESULTS.failed,
        num_steps=unknown,
        num_accepted_steps=unknown,
        num_rejected_steps=unknown,
    )


# ------------------------------------------------------------------------------ API
def save_trajectory(
    path: str | os.PathLike, traj: Trajectory, *, overwrite: bool = False
) -> pathlib.Path:
    """Write a trajectory to a ``.npz`` or ``.mat`` file (format from the suffix).

    ``.npz`` keeps everything (times, states, result code, step counters) exactly;
    ``.mat`` writes SoRoSim's ``DynamicsSolution.mat`` variables: ``t``
    (``n_save x 1``, [s]) and ``qqd`` (``n_save x 2 n_dof``, rows ``[q, qd]``), and
    drops the result code and counters. The file is written to a temporary sibling
    and moved into place when complete, so a failure never leaves a partial file.

    Args:
        path: target file (``str`` or ``pathlib.Path``), ending in ``.npz`` or
            ``.mat`` (any case).
        traj: the :class:`~sorojax.Trajectory` (from :func:`sorojax.simulate`, or
            built by hand). ``.npz`` also takes a batch of trajectories (leading
            batch axes, e.g. from ``jax.vmap``).
        overwrite: replace an existing file. By default an existing file is never
            touched.

    Returns:
        The path written, as a ``pathlib.Path``.

    Raises:
        TypeError: ``traj`` is not a ``Trajectory``, or ``path`` is not a path.
        ValueError: unknown suffix; a batch of trajectories given for ``.mat``.
        FileExistsError: ``path`` exists and ``overwrite`` is False.
        FileNotFoundError: the folder of ``path`` does not exist.

    Example:
        >>> traj = sorojax.simulate(linkage, 1.0)
        >>> save_trajectory("DynamicsSolution.mat", traj)  # for MATLAB / SoRoSim
    """
    path = as_path(path)
    if not isinstance(traj, Trajectory):
        raise TypeError(
            f"traj is a {type(traj).__name__}, not a sorojax.Trajectory: pass the "
            "result of sorojax.simulate (or a Trajectory built from t, q, qd)."
        )
    suffix = _suffix(path)
    save = _save_npz if suffix == ".npz" else _save_mat
    with writing(path, overwrite) as tmp:
        save(tmp, traj)
    return path


def load_trajectory(path: str | os.PathLike) -> Trajectory:
    """Read a trajectory written by :func:`save_trajectory` (or by SoRoSim).

    ``.npz``: the saved trajectory exactly (values, dtypes, result code, counters).
    JAX keeps float64 arrays as float64 only when ``jax_enable_x64`` is on; without
    it they come back as float32.

    ``.mat``: variables ``t`` (any vector, [s]) and ``qqd`` (``n_save x 2 n_dof``)
    as SoRoSim's ``DynamicsSolution.mat``; other variables are ignored. The file holds
    no solver information: ``num_steps``, ``num_accepted_steps`` and
    ``num_rejected_steps`` are -1 (unknown) and ``result`` is
    ``RESULTS.successful``, or ``RESULTS.failed`` if some state is not finite.

    Args:
        path: a ``.npz`` or ``.mat`` file (``str`` or ``pathlib.Path``).

    Returns:
        The :class:`~sorojax.Trajectory`.

    Raises:
        ValueError: unknown suffix; the file is not a trajectory (missing arrays or
            variables, inconsistent shapes, MATLAB v7.3 file).
        FileNotFoundError: ``path`` does not exist.
    """
    path = as_path(path)
    suffix = _suffix(path)
    if not path.is_file():
        raise FileNotFoundError(
            f"{str(path)!r} does not exist (or is not a file): check the path."
        )
    return _load_npz(path) if suffix == ".npz" else _load_mat(path)
