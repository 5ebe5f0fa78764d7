"""Safe file writing shared by the savers: no silent overwrite, no half-written files.

Every writer in :mod:`sorojax.io` and :mod:`sorojax.viz` goes through
:func:`writing`: it refuses an existing target unless ``overwrite=True``, lets the
caller write a temporary file next to the target (same suffix, so libraries that pick
the format from the name still do), and moves it into place only once it is complete.
A failed write leaves neither a partial file nor a damaged old one.
"""

import contextlib
import os
import pathlib
import uuid
from collections.abc import Iterator


def as_path(path: str | os.PathLike) -> pathlib.Path:
    """Return ``path`` (a ``str`` or any ``os.PathLike``) as a ``pathlib.Path``.

    Raises:
        TypeError: ``path`` is neither a string nor a path-like object.
    """
    if not isinstance(path, str | os.PathLike):
        raise TypeError(
            f"path = {path!r} ({type(path).__name__}) is not a file path: give a str "
            "or a pathlib.Path."
        )
    return pathlib.Path(os.fspath(path)).expanduser()


def check_target(path: pathlib.Path, overwrite: bool) -> None:
    """Raise unless ``path`` can be written.

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is False.
        IsADirectoryError: ``path`` is a directory.
        FileNotFoundError: the parent directory of ``path`` does not exist.
    """
    if path.is_dir():
        raise IsADirectoryError(
            f"{str(path)!r} is a directory: give a file name inside it."
        )
    if path.exists() and not overwrite:
        raise FileExistsError(
            f"{str(path)!r} already exists and was left unchanged: pass "
            "overwrite=True to replace it, or choose another file name."
        )
    if not path.parent.is_dir():
        raise FileNotFoundError(
            f"the folder {str(path.parent)!r} of {str(path)!r} does not exist: create "
            "it first (pathlib.Path(...).mkdir(parents=True))."
        )


@contextlib.contextmanager
def writing(path: pathlib.Path, overwrite: bool) -> Iterator[pathlib.Path]:
    """Context manager yielding a temporary path to write; moved to ``path`` on success.

    The temporary file is a hidden sibling of ``path`` with the same suffix; it is
    removed if the block raises. The target is checked before the block runs and
    again just before the move (a file created meanwhile is not overwritten unless
    ``overwrite`` is True).

    Raises:
        FileExistsError: ``path`` exists and ``overwrite`` is False.
        IsADirectoryError, FileNotFoundError: see :func:`check_target`.
    """
    check_target(path, overwrite)
    tmp = path.with_name(f".{path.stem}.{uuid.uuid4().hex[:12]}.partial{path.suffix}")
    try:
        yield tmp
        if not tmp.exists():
            raise RuntimeError(f"internal error: nothing was written to {str(tmp)!r}.")
        check_target(path, overwrite)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
