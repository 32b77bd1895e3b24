"""Files a user may hand us (demonstrations, videos, cached scenes and models): every loader fails with
:class:`DataFileError`, whose message starts with the file's path and says in one sentence what is wrong, never
with a library's own error (that stays attached as the cause, for debugging)."""

from __future__ import annotations

import pickle
import zipfile
import zlib
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

# What h5py, numpy, zipfile and torch raise on a truncated, corrupt or foreign file (torch's reader raises KeyError
# on arbitrary bytes).
UNREADABLE = (OSError, EOFError, ValueError, RuntimeError, KeyError, zipfile.BadZipFile, zlib.error,
              pickle.UnpicklingError)


class DataFileError(ValueError):
    """A file that cannot be used; the message starts with its path."""


def existing_file(path: str | Path) -> Path:
    """``path`` as a :class:`Path`, or :class:`DataFileError` when no file is there."""
    path = Path(path)
    if not path.exists():
        raise DataFileError(f"{path}: does not exist")
    if not path.is_file():
        raise DataFileError(f"{path}: is a directory, not a file")
    return path


@contextmanager
def reading(path: Path, kind: str) -> Iterator[None]:
    """Turn a library's error while reading ``path`` into "not a readable <kind> (truncated or corrupt?)"; a
    :class:`DataFileError` raised inside (a content check) passes unchanged."""
    try:
        yield
    except DataFileError:
        raise
    except UNREADABLE as err:
        raise DataFileError(f"{path}: not a readable {kind} (truncated or corrupt?)") from err


def read_npz(path: str | Path, required: Sequence[str]) -> dict[str, np.ndarray]:
    """Every array of an ``.npz`` written by :func:`numpy.savez_compressed` (no pickles), read at once; each name in
    ``required`` must be there."""
    path = existing_file(path)
    with reading(path, ".npz archive"):
        data = np.load(path, allow_pickle=False)
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise DataFileError(f"{path}: holds a single array, not an .npz archive of named arrays")
        with data:
            return _arrays(path, data, required)


def _arrays(path: Path, data: np.lib.npyio.NpzFile, required: Sequence[str]) -> dict[str, np.ndarray]:
    """The arrays of an open archive, after checking that the ``required`` ones are there."""
    missing = [k for k in required if k not in data.files]
    if missing:
        names = ", ".join(repr(k) for k in missing) + (" array" if len(missing) == 1 else " arrays")
        raise DataFileError(f"{path}: has no {names}; was it written by hrc_lab?")
    return {k: data[k] for k in data.files}  # each access to an npz member decompresses it again


def load_torch(path: str | Path) -> Any:
    """``torch.load`` of one of our artifacts on the CPU, weights only (tensors and plain Python values)."""
    import torch

    path = existing_file(path)
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except UNREADABLE as err:
        raise DataFileError(f"{path}: not a readable PyTorch weights file (truncated, corrupt, or holding objects "
                            "other than tensors and plain values?)") from err


def load_weights(path: Path, module: Any, state_dict: dict) -> None:
    """``module.load_state_dict(state_dict)``, the state read from ``path``; a mismatch names the file."""
    try:
        module.load_state_dict(state_dict)
    except (RuntimeError, TypeError) as err:
        raise DataFileError(f"{path}: its weights do not fit the network of this config (missing, unexpected or "
                            "differently shaped tensors)") from err
