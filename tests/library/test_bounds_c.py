"""Bounded work and type hints of ``cvkit.learn``, ``cvkit.nn`` and ``cvkit.train`` (issue #21).

Every size-like or cost-driving parameter given an extreme value is refused up front with a
``ValueError``/``TypeError`` naming the caller's argument, before anything large is allocated
(``bounds_harness.assert_refused``). Every public function of the three topics carries type
hints for all its parameters and its return.
"""
from __future__ import annotations

import importlib
import inspect
import pkgutil
import typing

import numpy as np
import pytest

from cvkit import learn, nn, train
from cvkit.learn import _common, _neighbours

try:
    from .bounds_harness import assert_refused
except ImportError:  # tests/ is not a package: pytest puts it on sys.path
    from bounds_harness import assert_refused

TOPICS = ("learn", "nn", "train")


def _big(shape):
    """An all-zero float64 array of ``shape`` that takes no memory (a broadcast view)."""
    return np.broadcast_to(0.0, shape)


def _xy(n=4):
    return np.tile([[0.0, 1.0], [1.0, 0.0]], (n // 2, 1)), np.tile([0, 1], n // 2)


def _cache(**changes):
    """A conv2d cache of a small layer, with some entries changed."""
    return {"x": np.zeros((1, 1, 4, 4)), "w": np.zeros((1, 1, 3, 3)), "b": np.zeros(1), "stride": 1,
            "padding": 0, **changes}


X_DIGITS = np.zeros((4, 8, 8))
Y_DIGITS = np.array([0, 1, 0, 1])

# (id, function, positional arguments, keyword arguments, names the error may give)
EXTREMES = [
    # ---------------------------------------------------------------------------- learn
    ("linear_scores classes x rows", learn.linear_scores,
     (np.zeros((100_000, 1)), np.zeros((100_000, 1)), np.zeros(100_000)), {}, "W"),
    ("sgd_train epochs", learn.sgd_train, (*_xy(), 2, 0.1, 10**9, 2), {}, "epochs"),
    ("sgd_train classes", learn.sgd_train, (*_xy(), 10**9, 0.1, 1, 2), {}, "classes"),
    ("sgd_train batch scores", learn.sgd_train,
     (np.zeros((20_000, 1)), np.zeros(20_000, dtype=int), 20_000, 0.1, 1, 20_000), {}, "batch_size"),
    ("numerical_gradient eps lost", learn.numerical_gradient, (lambda v: float(v.sum()), np.ones(3)),
     {"eps": 1e-300}, "eps"),
    ("numerical_gradient eps overflow", learn.numerical_gradient, (lambda v: float(v.sum()), np.full(2, 1e308)),
     {"eps": 1e308}, "eps"),
    ("knn_predict k", learn.knn_predict,
     (np.arange(100_000.0)[:, None], np.zeros(100_000, dtype=int), np.zeros((100_000, 1))), {"k": 50_000}, "k"),
    ("kmeans k", learn.kmeans, (np.arange(20_000.0)[:, None], 20_000), {"iterations": 1}, "k"),
    ("kmeans iterations", learn.kmeans, (np.arange(4.0)[:, None], 2), {"iterations": 10**9}, "iterations"),
    ("dense_descriptors bins", learn.dense_descriptors, (np.zeros((16, 16)),), {"bins": 10**6}, "bins"),
    ("dense_descriptors windows", learn.dense_descriptors, (_big((2000, 2000)),),
     {"size": 8, "step": 1, "cells": 8, "bins": 8}, "step"),
    # ---------------------------------------------------------------------------- nn
    ("conv2d_forward padding", nn.conv2d_forward, (np.zeros((1, 1, 4, 4)), np.zeros((1, 1, 3, 3)), np.zeros(1)),
     {"padding": 10**4}, "padding"),
    ("conv2d_forward padding rows", nn.conv2d_forward, (np.zeros((1, 1, 4, 4)), np.zeros((1, 1, 3, 3)), np.zeros(1)),
     {"padding": (10**9, 0)}, "padding"),
    ("conv2d_forward windows", nn.conv2d_forward, (_big((1, 256, 128, 128)), np.zeros((1, 256, 11, 11)), np.zeros(1)),
     {}, "x"),
    ("conv2d_backward cache padding", nn.conv2d_backward, (np.zeros(1), _cache(padding=10**4)), {}, "cache['padding']"),
    ("maxpool2d_forward size", nn.maxpool2d_forward, (np.zeros((1, 1, 4, 4)),), {"size": 10**4}, "size"),
    ("maxpool2d_forward windows", nn.maxpool2d_forward, (_big((1, 1, 1000, 1000)),), {"size": 500, "stride": 1},
     "size"),
    ("maxpool2d_backward cache size", nn.maxpool2d_backward,
     (np.zeros(1), {"x": np.zeros((1, 1, 4, 4)), "size": 10**4, "stride": 2}), {}, "cache['size']"),
    ("linear_forward outputs", nn.linear_forward, (np.zeros((100_000, 1)), np.zeros((1, 100_000)), np.zeros(100_000)),
     {}, "W"),
    ("residual_block_forward windows", nn.residual_block_forward, (_big((1, 32, 1024, 1024)), {
        "w1": np.zeros((32, 32, 3, 3)), "w2": np.zeros((32, 32, 3, 3)),
        **{f"{k}{i}": np.ones(32) for i in (1, 2) for k in ("gamma", "beta", "running_mean", "running_var")}}),
     {}, "x"),
    ("SmallCNN channels", nn.SmallCNN, (), {"channels": (10**5, 10**5)}, "channels"),
    ("SmallCNN classes", nn.SmallCNN, (), {"classes": 10**9}, "classes"),
    ("SmallCNN.new_head classes", nn.SmallCNN(rng=0).new_head, (10**9,), {}, "classes"),
    ("SmallCNN.fit epochs", nn.SmallCNN(rng=0).fit, (X_DIGITS, Y_DIGITS), {"epochs": 10**9}, "epochs"),
    ("SmallCNN.fit shift", nn.SmallCNN(rng=0).fit, (X_DIGITS, Y_DIGITS), {"epochs": 1, "shift": 10**4}, "shift"),
    ("SmallCNN.scores batch", nn.SmallCNN(rng=0).scores, (_big((500_000, 1, 8, 8)),), {}, "X"),
    ("SmallCNN.scores tiny images", nn.SmallCNN(rng=0).scores, (np.zeros((2, 3, 3)),), {}, "X"),
    # ---------------------------------------------------------------------------- train
    ("random_search trials", train.random_search, ({"lr": [0.1, 1.0]}, 10**9), {}, "trials"),
    ("smooth_labels classes", train.smooth_labels, (np.zeros(100_000, dtype=int), 10**5, 0.1), {}, "classes"),
    ("random_resized_crop output_size", train.random_resized_crop, (np.zeros((8, 8)), 10**6), {}, "output_size"),
    ("random_resized_crop output_size pair", train.random_resized_crop, (np.zeros((8, 8, 3)), (10**5, 10**4)), {},
     "output_size"),
    ("one_cycle div", train.one_cycle, (0, 10, 1.0), {"div": 1e-320}, "div"),
    ("one_cycle final_div", train.one_cycle, (0, 10, 1.0), {"final_div": 1e-320}, "final_div"),
]


@pytest.mark.parametrize(("fn", "args", "kwargs", "names"), [case[1:] for case in EXTREMES],
                         ids=[case[0] for case in EXTREMES])
def test_extreme_values_are_refused_naming_the_argument(fn, args, kwargs, names):
    error = assert_refused(fn, *args, names=names, **kwargs)
    assert isinstance(error, ValueError)


def test_maxpool_speaks_of_size_not_kernel():
    error = assert_refused(nn.maxpool2d_forward, np.zeros((1, 1, 4, 4)), size=10**4, names="size")
    assert "kernel" not in str(error) and "4 × 4" in str(error)


def test_conv_kernel_larger_than_input_names_w():
    error = assert_refused(nn.conv2d_forward, np.zeros((1, 1, 2, 2)), np.zeros((1, 1, 3, 3)), np.zeros(1),
                           names="w's kernel")
    assert "2 + 2·0" in str(error)


def test_refusals_leave_reasonable_calls_alone():
    """Values just inside the bounds work as before."""
    X, y = _xy()
    assert learn.sgd_train(X, y, 2, 0.1, 3, 4, rng=0)[2].shape == (3,)
    out, _ = nn.conv2d_forward(np.ones((1, 1, 4, 4)), np.ones((1, 1, 3, 3)), np.zeros(1), padding=2)
    assert out.shape == (1, 1, 6, 6) and out[0, 0, 0, 0] == 1.0
    assert nn.maxpool2d_forward(np.arange(16.0).reshape(1, 1, 4, 4), size=4)[0].item() == 15.0
    assert len(train.random_search({"lr": [0.1]}, 0)) == 0
    assert learn.dense_descriptors(np.random.default_rng(0).random((16, 16)), bins=360).shape == (9, 4 * 360)


def test_knn_labels_may_be_huge_numbers():
    X_train = np.array([[0.0], [1.0], [10.0], [11.0]])
    y_train = np.array([10**12, 10**12, 3, 3])
    assert learn.knn_predict(X_train, y_train, np.array([[0.5], [10.5], [3.0], [5.4]]), k=2).tolist() == [10**12, 3, 10**12, 3]
    assert learn.knn_predict(X_train, y_train, np.array([[5.5]]), k=4).tolist() == [3]  # vote tie: smallest label


@pytest.mark.parametrize("metric", ["l2", "l1"])
def test_knn_and_bovw_in_small_blocks_equal_the_brute_force(monkeypatch, metric):
    rng = np.random.default_rng(7)
    X_train = rng.integers(0, 3, (60, 5)).astype(float)          # many exact ties
    y_train = rng.integers(0, 4, 60)
    X_test = rng.integers(0, 3, (23, 5)).astype(float)
    expected = [learn.knn_predict(X_train, y_train, X_test, k=k, metric=metric) for k in (1, 5, 20, 60)]
    descriptors, codebook = rng.normal(size=(50, 3)), rng.normal(size=(7, 3))
    histogram = learn.bovw_histogram(descriptors, codebook)
    diff = X_test[:, None, :] - X_train[None, :, :]
    distances = (diff**2).sum(axis=2) if metric == "l2" else np.abs(diff).sum(axis=2)
    brute = np.argsort(distances, axis=1, kind="stable")
    for k, got in zip((1, 5, 20, 60), expected):
        votes = y_train[brute[:, :k]]
        counts = np.stack([np.bincount(row, minlength=4) for row in votes])
        np.testing.assert_array_equal(got, counts.argmax(axis=1))
    for module in (_common, _neighbours):
        monkeypatch.setattr(module, "_CHUNK_ELEMENTS", 7)
    monkeypatch.setattr(_neighbours, "_ROWS_ELEMENTS", 50)
    for k, before in zip((1, 5, 20, 60), expected):
        np.testing.assert_array_equal(learn.knn_predict(X_train, y_train, X_test, k=k, metric=metric), before)
    np.testing.assert_array_equal(learn.bovw_histogram(descriptors, codebook), histogram)


# ------------------------------------------------------------------------------ type hints
def _public_callables(topic: str):
    """Every public function and public method of a class of the topic: the names of its
    ``__all__`` and everything public defined in its modules (``checks`` is not the library's)."""
    package = importlib.import_module(f"cvkit.{topic}")
    found = {}
    modules = [package] + [importlib.import_module(f"{package.__name__}.{info.name}")
                           for info in pkgutil.iter_modules(package.__path__) if info.name != "checks"]
    for module in modules:
        names = set(getattr(module, "__all__", ())) if module is package else set(vars(module))
        for name in names:
            obj = getattr(module, name)
            if name.startswith("_") or getattr(obj, "__module__", None) is None:
                continue
            if not obj.__module__.startswith(package.__name__) or obj.__module__.endswith(".checks"):
                continue
            if inspect.isfunction(obj):
                found[f"{obj.__module__}.{obj.__qualname__}"] = obj
            elif inspect.isclass(obj):
                source = inspect.getsourcefile(obj)
                for attr, member in vars(obj).items():
                    member = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
                    if not inspect.isfunction(member) or (attr.startswith("_") and attr != "__init__"):
                        continue
                    if member.__code__.co_filename == source:  # not a dataclass's generated method
                        found[f"{obj.__module__}.{member.__qualname__}"] = member
    for name in getattr(package, "__all__", ()):
        assert name in vars(package), f"cvkit.{topic}.__all__ names {name}, which it lacks"
    return found


PUBLIC = {name: fn for topic in TOPICS for name, fn in _public_callables(topic).items()}


def test_the_walk_finds_the_public_api():
    for expected in ("cvkit.learn._linear.sgd_train", "cvkit.nn._conv.conv2d_forward",
                     "cvkit.nn._model.SmallCNN.fit", "cvkit.nn._model.SmallCNN.__init__",
                     "cvkit.train._recipes.random_search", "cvkit.train._models.train"):
        assert expected in PUBLIC
    for topic, module in (("learn", learn), ("nn", nn), ("train", train)):
        functions = [n for n in module.__all__ if inspect.isfunction(getattr(module, n))]
        assert all(any(key.endswith(f".{n}") for key in PUBLIC) for n in functions), topic


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_public_function_is_fully_annotated(name):
    fn = PUBLIC[name]
    hints = typing.get_type_hints(fn)   # also proves that every annotation resolves
    parameters = [p for p in inspect.signature(fn).parameters.values() if p.name not in ("self", "cls")]
    missing = [p.name for p in parameters if p.name not in hints]
    assert not missing, f"{name}: parameters without a type hint: {missing}"
    assert "return" in hints, f"{name}: no return type"
