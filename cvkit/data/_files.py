"""Readers of the official MNIST (IDX) and CIFAR-10 (python pickle batches) file formats.

cvkit never downloads anything: these readers are for users who already have the files
(the notebooks use the embedded :func:`cvkit.data.digits` instead).

- **IDX** (MNIST, Fashion-MNIST, EMNIST): a big-endian header — two zero bytes, a type code
  (0x08 uint8, 0x09 int8, 0x0B int16, 0x0C int32, 0x0D float32, 0x0E float64), the number
  of dimensions — then one 4-byte big-endian size per dimension and the values in C order.
  Files may be gzip-compressed (``.gz``), as distributed.
- **CIFAR-10 python batches** (``cifar-10-batches-py/data_batch_1`` … ``test_batch``): a
  pickled dict with ``b"data"``, a ``(N, 3072)`` uint8 array whose rows hold the red, then
  green, then blue 32×32 plane in row-major order, and ``b"labels"``, a list of N integers.
  Pickles can run code when loaded, so these files are read by an unpickler that accepts only
  plain containers and NumPy arrays.
"""
from __future__ import annotations

import gzip
import io
import os
import pickle
import struct
from pathlib import Path
from typing import Any

import numpy as np

from ._digits import Split

__all__ = ["read_idx", "mnist", "read_cifar_batch", "cifar10", "CIFAR10_CLASSES"]

#: the CIFAR-10 class names in label order (also in the ``batches.meta`` file)
CIFAR10_CLASSES = ("airplane", "automobile", "bird", "cat", "deer", "dog", "frog", "horse", "ship", "truck")

#: a file or folder path
PathLike = str | os.PathLike[str]

_IDX_TYPES = {0x08: ">u1", 0x09: ">i1", 0x0B: ">i2", 0x0C: ">i4", 0x0D: ">f4", 0x0E: ">f8"}
_MNIST_FILES = {
    "train_images": "train-images-idx3-ubyte",
    "train_labels": "train-labels-idx1-ubyte",
    "test_images": "t10k-images-idx3-ubyte",
    "test_labels": "t10k-labels-idx1-ubyte",
}


def _path(path: PathLike, name: str = "path") -> Path:
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{name} must be a file path (str or os.PathLike), got {type(path).__name__}")
    return Path(path)


def _read_bytes(path: Path) -> bytes:
    raw = path.read_bytes()
    if raw[:2] == b"\x1f\x8b":  # gzip magic number, whatever the file's name
        raw = gzip.decompress(raw)
    return raw


def read_idx(path: PathLike) -> np.ndarray:
    """Read one IDX file (gzip-compressed or not) into an array.

    Parameters
    ----------
    path : str or os.PathLike
        E.g. ``train-images-idx3-ubyte`` or ``train-images-idx3-ubyte.gz``.

    Returns
    -------
    ndarray
        Of the file's shape and type (native byte order): uint8 ``(60000, 28, 28)`` for the
        MNIST training images, uint8 ``(60000,)`` for its labels.

    Raises
    ------
    ValueError
        If the header is not an IDX header or the file is shorter or longer than it says.

    Examples
    --------
    >>> import os, struct, tempfile
    >>> folder = tempfile.mkdtemp()
    >>> name = os.path.join(folder, "tiny-idx2-ubyte")
    >>> with open(name, "wb") as f:
    ...     _ = f.write(struct.pack(">BBBBII", 0, 0, 0x08, 2, 2, 3) + bytes(range(6)))
    >>> read_idx(name)
    array([[0, 1, 2],
           [3, 4, 5]], dtype=uint8)
    """
    path = _path(path)
    raw = _read_bytes(path)
    if len(raw) < 4 or raw[0] != 0 or raw[1] != 0:
        raise ValueError(f"{path}: not an IDX file (it must start with two zero bytes)")
    code, ndim = raw[2], raw[3]
    if code not in _IDX_TYPES:
        raise ValueError(f"{path}: unknown IDX type code 0x{code:02X} (expected one of "
                         + ", ".join(f"0x{c:02X}" for c in _IDX_TYPES) + ")")
    header = 4 + 4 * ndim
    if len(raw) < header:
        raise ValueError(f"{path}: truncated IDX header ({len(raw)} bytes for {ndim} dimensions)")
    shape = struct.unpack(f">{ndim}I", raw[4:header])
    dtype = np.dtype(_IDX_TYPES[code])
    expected = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    if len(raw) - header != expected:
        raise ValueError(f"{path}: the header announces shape {shape} ({expected} bytes of data) "
                         f"but the file holds {len(raw) - header} bytes after it")
    data = np.frombuffer(raw, dtype=dtype, offset=header).reshape(shape)
    return data.astype(dtype.newbyteorder("="))


def _find(folder: Path, stem: str) -> Path:
    # the official names, their .gz versions, and the "train-images.idx3-ubyte" spelling
    variants = [stem, stem + ".gz"]
    dotted = stem.replace("-idx", ".idx")
    variants += [dotted, dotted + ".gz"]
    for name in variants:
        if (folder / name).is_file():
            return folder / name
    raise FileNotFoundError(f"{folder}: no file {stem}[.gz] (looked for {', '.join(variants)})")


def mnist(folder: PathLike, flatten: bool = False, raw: bool = False) -> Split:
    """The MNIST training and test sets from the four official IDX files in ``folder``.

    Parameters
    ----------
    folder : str or os.PathLike
        A folder holding ``train-images-idx3-ubyte``, ``train-labels-idx1-ubyte``,
        ``t10k-images-idx3-ubyte`` and ``t10k-labels-idx1-ubyte`` (each possibly ``.gz``).
    flatten : bool
        Return each image as a 784-vector instead of 28×28.
    raw : bool
        Return the images as the file's uint8 values 0..255 (a quarter of the memory)
        instead of float64 in [0, 1].

    Returns
    -------
    (X_train, y_train), (X_test, y_test)
        ``X`` float64 in [0, 1] (value / 255), ``(N, 28, 28)`` or ``(N, 784)``; ``y`` int64
        labels 0..9. The official split: 60000 training and 10000 test images.
    """
    folder = _path(folder, "folder")
    if not folder.is_dir():
        raise FileNotFoundError(f"folder {folder} does not exist")
    parts = {key: read_idx(_find(folder, stem)) for key, stem in _MNIST_FILES.items()}
    out: list[tuple[np.ndarray, np.ndarray]] = []
    for split in ("train", "test"):
        images, labels = parts[f"{split}_images"], parts[f"{split}_labels"]
        if images.ndim != 3 or labels.ndim != 1 or len(images) != len(labels):
            raise ValueError(f"{folder}: {split} images {images.shape} and labels {labels.shape} do not match")
        X = images if raw else images.astype(np.float64) / 255.0
        if flatten:
            X = X.reshape(len(X), -1)
        out.append((X, labels.astype(np.int64)))
    return out[0], out[1]


class _SafeUnpickler(pickle.Unpickler):
    """Unpickles containers, numbers, strings and NumPy arrays, and nothing else."""

    _ALLOWED = {
        ("numpy.core.multiarray", "_reconstruct"),
        ("numpy._core.multiarray", "_reconstruct"),
        ("numpy._core.numeric", "_frombuffer"),
        ("numpy.core.numeric", "_frombuffer"),
        ("numpy", "ndarray"),
        ("numpy", "dtype"),
        ("numpy.core.multiarray", "scalar"),
        ("numpy._core.multiarray", "scalar"),
        ("_codecs", "encode"),
        ("copy_reg", "_reconstructor"),
        ("copyreg", "_reconstructor"),
        ("__builtin__", "object"),
        ("builtins", "object"),
    }

    def find_class(self, module: str, name: str) -> Any:
        if (module, name) in self._ALLOWED:
            return super().find_class(module, name)
        raise pickle.UnpicklingError(f"refusing to load {module}.{name} from a data file")


def _load_pickle(path: Path) -> Any:
    with io.BytesIO(_read_bytes(path)) as stream:
        return _SafeUnpickler(stream, encoding="bytes").load()


def _get(batch: dict[Any, Any], key: str) -> Any:
    for k in (key.encode(), key):
        if k in batch:
            return batch[k]
    raise KeyError(key)


def read_cifar_batch(path: PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Read one CIFAR-10 (or CIFAR-100) python batch file.

    Parameters
    ----------
    path : str or os.PathLike
        E.g. ``cifar-10-batches-py/data_batch_1`` or ``test_batch``.

    Returns
    -------
    images : (N, 32, 32, 3) uint8 ndarray
        RGB images indexed ``[row, col, channel]`` (the file stores each image as the red,
        green and blue 32×32 planes one after the other).
    labels : (N,) int64 ndarray
        ``b"labels"`` (CIFAR-10) or ``b"fine_labels"`` (CIFAR-100).

    Examples
    --------
    >>> import os, pickle, tempfile
    >>> import numpy as np
    >>> rows = np.zeros((2, 3072), dtype=np.uint8)      # two fake images, stored plane by plane:
    >>> rows[:, :1024], rows[:, 1024:2048] = 200, 100    # red 200, green 100, blue 0
    >>> path = os.path.join(tempfile.mkdtemp(), "data_batch_1")
    >>> with open(path, "wb") as f:
    ...     pickle.dump({b"data": rows, b"labels": [3, 7]}, f, protocol=2)
    >>> images, labels = read_cifar_batch(path)
    >>> images.shape, labels.tolist(), images[0, 5, 7].tolist()   # pixel (5, 7): R, G, B
    ((2, 32, 32, 3), [3, 7], [200, 100, 0])
    """
    path = _path(path)
    batch = _load_pickle(path)
    if not isinstance(batch, dict):
        raise ValueError(f"{path}: not a CIFAR batch (expected a pickled dict, got {type(batch).__name__})")
    try:
        data = np.asarray(_get(batch, "data"))
    except KeyError:
        raise ValueError(f"{path}: not a CIFAR batch (no 'data' entry)") from None
    labels = None
    for key in ("labels", "fine_labels"):
        try:
            labels = np.asarray(_get(batch, key), dtype=np.int64)
            break
        except KeyError:
            continue
    if labels is None:
        raise ValueError(f"{path}: not a CIFAR batch (no 'labels' or 'fine_labels' entry)")
    if data.ndim != 2 or data.shape[1] != 3072 or data.dtype != np.uint8:
        raise ValueError(f"{path}: 'data' must be an (N, 3072) uint8 array, got {data.dtype} {data.shape}")
    if labels.shape != (data.shape[0],):
        raise ValueError(f"{path}: {data.shape[0]} images but {labels.size} labels")
    images = data.reshape(-1, 3, 32, 32).transpose(0, 2, 3, 1)
    return np.ascontiguousarray(images), labels


def cifar10(folder: PathLike, flatten: bool = False, raw: bool = False) -> Split:
    """The CIFAR-10 training and test sets from the python batches in ``folder``.

    Parameters
    ----------
    folder : str or os.PathLike
        The ``cifar-10-batches-py`` folder: ``data_batch_1`` … ``data_batch_5`` and
        ``test_batch``. Training batches that are missing are skipped (at least one is needed).
    flatten : bool
        Return each image as a 3072-vector (in ``[row, col, channel]`` order) instead of
        ``(32, 32, 3)``.
    raw : bool
        Return uint8 values 0..255 instead of float64 in [0, 1] (the float64 training set
        takes 1.2 GB).

    Returns
    -------
    (X_train, y_train), (X_test, y_test)
        ``X`` float64 in [0, 1], ``(N, 32, 32, 3)``; ``y`` int64 labels 0..9, named by
        :data:`CIFAR10_CLASSES`. The official split: 50000 training and 10000 test images.
    """
    folder = _path(folder, "folder")
    if not folder.is_dir():
        raise FileNotFoundError(f"folder {folder} does not exist")
    train = [folder / f"data_batch_{i}" for i in range(1, 6) if (folder / f"data_batch_{i}").is_file()]
    if not train:
        raise FileNotFoundError(f"{folder}: no data_batch_1 … data_batch_5")
    if not (folder / "test_batch").is_file():
        raise FileNotFoundError(f"{folder}: no test_batch")
    out: list[tuple[np.ndarray, np.ndarray]] = []
    for files in (train, [folder / "test_batch"]):
        parts = [read_cifar_batch(f) for f in files]
        images = np.concatenate([p[0] for p in parts])
        labels = np.concatenate([p[1] for p in parts])
        X = images if raw else images.astype(np.float64) / 255.0
        if flatten:
            X = X.reshape(len(X), -1)
        out.append((X, labels))
    return out[0], out[1]
