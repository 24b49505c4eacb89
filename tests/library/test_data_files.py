"""Readers of the MNIST (IDX) and CIFAR-10 (python pickle batches) formats, tested on tiny
files written here in those formats (by an independent writer), and the texture patches."""
from __future__ import annotations

import gzip
import os
import pickle
import struct

import numpy as np
import pytest

from cvkit import data

RNG = np.random.default_rng(99)
IDX_CODES = {np.dtype(np.uint8): 0x08, np.dtype(np.int8): 0x09, np.dtype(">i2"): 0x0B, np.dtype(">i4"): 0x0C,
             np.dtype(">f4"): 0x0D, np.dtype(">f8"): 0x0E}


def write_idx(path, array, compress=False):
    """The IDX format as documented by LeCun et al.: 0, 0, type, ndim, big-endian sizes, data."""
    array = np.asarray(array)
    big = array.astype(array.dtype.newbyteorder(">")) if array.dtype.itemsize > 1 else array
    header = bytes([0, 0, IDX_CODES[big.dtype], array.ndim]) + b"".join(struct.pack(">I", n) for n in array.shape)
    raw = header + big.tobytes(order="C")
    with open(path, "wb") as f:
        f.write(gzip.compress(raw) if compress else raw)


# --------------------------------------------------------------------------------------------
# IDX / MNIST
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("dtype", [np.uint8, np.int8, ">i2", ">i4", ">f4", ">f8"])
@pytest.mark.parametrize("compress", [False, True])
def test_read_idx_round_trip(tmp_path, dtype, compress):
    values = RNG.integers(-100, 100, (3, 4, 5)) if np.dtype(dtype).kind != "u" else RNG.integers(0, 256, (3, 4, 5))
    array = values.astype(dtype)
    path = tmp_path / "file-idx3"
    write_idx(path, array, compress)
    back = data.read_idx(path)
    assert back.shape == (3, 4, 5) and np.array_equal(back, array)
    assert back.dtype.isnative and back.dtype.kind == np.dtype(dtype).kind


def test_read_idx_refuses_broken_files(tmp_path):
    path = tmp_path / "bad"
    path.write_bytes(b"\x01\x00\x08\x01\x00\x00\x00\x02ab")
    with pytest.raises(ValueError, match="not an IDX file"):
        data.read_idx(path)
    path.write_bytes(b"\x00\x00\x07\x01\x00\x00\x00\x02ab")
    with pytest.raises(ValueError, match="unknown IDX type code 0x07"):
        data.read_idx(path)
    path.write_bytes(b"\x00\x00\x08\x02\x00\x00\x00\x02")
    with pytest.raises(ValueError, match="truncated IDX header"):
        data.read_idx(path)
    path.write_bytes(b"\x00\x00\x08\x01\x00\x00\x00\x03ab")
    with pytest.raises(ValueError, match="holds 2 bytes"):
        data.read_idx(path)
    with pytest.raises(TypeError, match="path must be a file path"):
        data.read_idx(3)


def _mnist_folder(folder, compress=False, dotted=False, n_train=6, n_test=4):
    images = {"train": RNG.integers(0, 256, (n_train, 28, 28), dtype=np.uint8),
              "t10k": RNG.integers(0, 256, (n_test, 28, 28), dtype=np.uint8)}
    labels = {"train": RNG.integers(0, 10, n_train, dtype=np.uint8), "t10k": RNG.integers(0, 10, n_test, dtype=np.uint8)}
    for split in ("train", "t10k"):
        sep = "." if dotted else "-"
        suffix = ".gz" if compress else ""
        write_idx(folder / f"{split}-images{sep}idx3-ubyte{suffix}", images[split], compress)
        write_idx(folder / f"{split}-labels{sep}idx1-ubyte{suffix}", labels[split], compress)
    return images, labels


@pytest.mark.parametrize(("compress", "dotted"), [(False, False), (True, False), (False, True)])
def test_mnist_reads_the_four_official_files(tmp_path, compress, dotted):
    images, labels = _mnist_folder(tmp_path, compress, dotted)
    (X_train, y_train), (X_test, y_test) = data.mnist(tmp_path)
    assert X_train.shape == (6, 28, 28) and X_test.shape == (4, 28, 28)
    assert X_train.dtype == np.float64 and np.allclose(X_train * 255, images["train"])
    assert y_train.dtype == np.int64 and np.array_equal(y_test, labels["t10k"])
    (F, _), _ = data.mnist(tmp_path, flatten=True)
    assert F.shape == (6, 784) and np.array_equal(F[2], X_train[2].ravel())
    (R, _), _ = data.mnist(tmp_path, raw=True)
    assert R.dtype == np.uint8 and np.array_equal(R, images["train"])


def test_mnist_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="does not exist"):
        data.mnist(tmp_path / "nowhere")
    _mnist_folder(tmp_path)
    os.remove(tmp_path / "t10k-labels-idx1-ubyte")
    with pytest.raises(FileNotFoundError, match="t10k-labels-idx1-ubyte"):
        data.mnist(tmp_path)
    write_idx(tmp_path / "t10k-labels-idx1-ubyte", np.zeros(3, np.uint8))  # 4 images, 3 labels
    with pytest.raises(ValueError, match="do not match"):
        data.mnist(tmp_path)


# --------------------------------------------------------------------------------------------
# CIFAR-10
# --------------------------------------------------------------------------------------------
def _cifar_rows(images):
    """The file layout: per image the red, green, blue 32×32 planes, each row-major."""
    return np.stack([np.concatenate([img[:, :, ch].ravel() for ch in range(3)]) for img in images])


def _cifar_batch(path, images, labels, protocol=2, key=b"labels"):
    batch = {b"batch_label": b"testing batch 1 of 1", key: list(map(int, labels)),
             b"data": _cifar_rows(images), b"filenames": [b"img_%d.png" % i for i in range(len(labels))]}
    with open(path, "wb") as f:
        pickle.dump(batch, f, protocol=protocol)


@pytest.mark.parametrize("protocol", [2, 4, 5])
def test_read_cifar_batch_layout(tmp_path, protocol):
    images = RNG.integers(0, 256, (3, 32, 32, 3), dtype=np.uint8)
    labels = [4, 0, 9]
    _cifar_batch(tmp_path / "data_batch_1", images, labels, protocol)
    got, got_labels = data.read_cifar_batch(tmp_path / "data_batch_1")
    assert got.shape == (3, 32, 32, 3) and got.dtype == np.uint8
    assert np.array_equal(got, images) and got_labels.tolist() == labels
    rows = _cifar_rows(images)
    r, c = 5, 17  # pixel (row 5, col 17), green: index 1024 + 5·32 + 17 in the file
    assert got[1, r, c, 1] == rows[1, 1024 + r * 32 + c]


def test_read_cifar100_fine_labels(tmp_path):
    images = RNG.integers(0, 256, (2, 32, 32, 3), dtype=np.uint8)
    _cifar_batch(tmp_path / "train", images, [57, 3], key=b"fine_labels")
    assert data.read_cifar_batch(tmp_path / "train")[1].tolist() == [57, 3]


def test_cifar10_folder(tmp_path):
    parts = []
    for i in (1, 2):
        images = RNG.integers(0, 256, (2, 32, 32, 3), dtype=np.uint8)
        labels = RNG.integers(0, 10, 2)
        _cifar_batch(tmp_path / f"data_batch_{i}", images, labels)
        parts.append((images, labels))
    test_images = RNG.integers(0, 256, (3, 32, 32, 3), dtype=np.uint8)
    _cifar_batch(tmp_path / "test_batch", test_images, [1, 2, 3])
    (X_train, y_train), (X_test, y_test) = data.cifar10(tmp_path)
    assert X_train.shape == (4, 32, 32, 3) and X_train.dtype == np.float64
    assert np.allclose(X_train * 255, np.concatenate([p[0] for p in parts]))  # batch 1 then batch 2
    assert y_train.tolist() == np.concatenate([p[1] for p in parts]).tolist()
    assert np.allclose(X_test * 255, test_images) and y_test.tolist() == [1, 2, 3]
    (F, _), _ = data.cifar10(tmp_path, flatten=True)
    assert F.shape == (4, 3072)
    (R, _), _ = data.cifar10(tmp_path, raw=True)
    assert R.dtype == np.uint8
    assert len(data.CIFAR10_CLASSES) == 10 and data.CIFAR10_CLASSES[3] == "cat"
    os.remove(tmp_path / "test_batch")
    with pytest.raises(FileNotFoundError, match="test_batch"):
        data.cifar10(tmp_path)


class _Exploit:
    def __reduce__(self):
        return (os.system, ("echo exploited",))


def test_cifar_reader_refuses_code_in_pickles(tmp_path):
    path = tmp_path / "data_batch_1"
    with open(path, "wb") as f:
        pickle.dump({b"data": _Exploit(), b"labels": [0]}, f)
    with pytest.raises(pickle.UnpicklingError, match="refusing to load"):
        data.read_cifar_batch(path)


def test_cifar_reader_refuses_other_pickles(tmp_path):
    path = tmp_path / "x"
    with open(path, "wb") as f:
        pickle.dump([1, 2, 3], f)
    with pytest.raises(ValueError, match="not a CIFAR batch"):
        data.read_cifar_batch(path)
    with open(path, "wb") as f:
        pickle.dump({b"data": np.zeros((2, 100), np.uint8), b"labels": [0, 1]}, f)
    with pytest.raises(ValueError, match=r"\(N, 3072\) uint8"):
        data.read_cifar_batch(path)


# --------------------------------------------------------------------------------------------
# scikit-image's bundled images
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["camera", "astronaut", "coins", "moon", "text", "brick", "coffee", "chelsea",
                                  "grass", "gravel"])
def test_bundled_images_are_scikit_images_own(name):
    """cvkit reads the PNG files itself (faster than skimage.io's first import): the same pixels."""
    import skimage.data

    expected = getattr(skimage.data, name)()
    got = data.image(name)
    assert got.dtype == np.float64 and got.shape == expected.shape
    assert np.array_equal(got, expected / 255.0)
    if hasattr(data, name):
        assert np.array_equal(getattr(data, name)(), got)


# --------------------------------------------------------------------------------------------
# textures
# --------------------------------------------------------------------------------------------
def test_textures_split_and_patches():
    import skimage.data

    (X_train, y_train), (X_test, y_test) = data.textures()
    assert X_train.shape == (576, 32, 32) and X_test.shape == (192, 32, 32)
    assert np.bincount(y_train).tolist() == [192] * 3 and np.bincount(y_test).tolist() == [64] * 3
    assert X_train.dtype == np.float64 and 0.0 <= X_train.min() and X_train.max() <= 1.0
    grass = skimage.data.grass() / 255.0
    assert np.array_equal(X_train[192], grass[:32, :32])            # first grass training patch
    assert np.array_equal(X_train[193], grass[:32, 32:64])          # row-major over the grid
    assert np.array_equal(X_test[64], grass[:32, 384:416])          # test patches: columns 384..511
    (F, _), _ = data.textures(patch_size=16, flatten=True)
    assert F.shape == (3 * 32 * 24, 256)
    assert data.TEXTURE_CLASSES == ("brick", "grass", "gravel")
    with pytest.raises(ValueError, match="patch_size must be >= 8"):
        data.textures(patch_size=4)
    with pytest.raises(ValueError, match="at most 128"):
        data.textures(patch_size=200)
