"""Argument checks shared by the Chapter 2 functions (scalars or arrays of physical values)."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .._validation import as_float_array

#: what the scalar functions return: an array, or a NumPy float for a scalar input
Values = np.ndarray | np.float64


def as_values(value: ArrayLike, name: str, *, allow_nan: bool = False, allow_inf: bool = False) -> np.ndarray:
    """``value`` (a number or an array of any shape) as a float64 array.

    NaN and ±inf are refused unless allowed; the message names the argument.
    """
    array = as_float_array(value, name, finite=False, allow_empty=True)
    if not allow_nan and np.isnan(array).any():
        raise ValueError(f"{name} must not contain NaN")
    if not allow_inf and np.isinf(array).any():
        raise ValueError(f"{name} must be finite (found inf)")
    return array


def scalar_or_array(result: np.ndarray) -> Values:
    """A 0-d result as a NumPy scalar (like a ufunc), anything else as the array."""
    return result[()] if result.ndim == 0 else result
