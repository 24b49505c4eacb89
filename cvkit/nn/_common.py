"""Argument checks shared by the layers of :mod:`cvkit.nn`."""
from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array, check_bool, check_int, check_real

__all__ = ["as_batch", "as_gradient", "pair", "check_bool", "check_cache", "entry_name"]


def as_batch(x: ArrayLike, name: str = "x") -> np.ndarray:
    """A batch of feature maps ``(N, C, H, W)`` as float64 (any real dtype accepted)."""
    return as_float_array(x, name, ndim=4)


def as_gradient(dout: ArrayLike, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """An upstream gradient of exactly ``shape``."""
    g = as_float_array(dout, name, ndim=len(shape), allow_empty=True)
    if g.shape != tuple(shape):
        raise ValueError(f"{name} must have the shape of the forward's output {tuple(shape)}, got {g.shape}")
    return g


def pair(value: int | Sequence[int] | np.ndarray, name: str, *, minimum: int) -> tuple[int, int]:
    """An int or a pair of ints ``(for rows, for columns)``, each at least ``minimum``."""
    if isinstance(value, (tuple, list, np.ndarray)):
        items = list(np.asarray(value).ravel()) if isinstance(value, np.ndarray) else list(value)
        if len(items) != 2:
            raise ValueError(f"{name} must be an int or a pair (rows, cols), got {value!r}")
        return (check_int(items[0], name, minimum=minimum), check_int(items[1], name, minimum=minimum))
    v = check_int(value, name, minimum=minimum)
    return (v, v)


def entry_name(prefix: str, key: str) -> str:
    """How an error names the argument ``key``: ``key`` itself, or ``prefix[key]``
    (``cache['x']``) when the arguments are the entries of a cache."""
    return f"{prefix}[{key!r}]" if prefix else key


def check_cache(cache: object, keys: tuple[str, ...], layer: str) -> dict[str, Any]:
    """``cache`` must be the dict of ``<layer>_forward`` holding ``keys``."""
    if not isinstance(cache, dict):
        raise TypeError(f"cache must be the dict returned by {layer}_forward, got {type(cache).__name__}")
    missing = [k for k in keys if k not in cache]
    if missing:
        raise ValueError(f"cache lacks {', '.join(map(repr, missing))}: pass the cache returned by {layer}_forward")
    return cache


def real(value: float, name: str, **kw: bool) -> float:
    return check_real(value, name, **kw)

