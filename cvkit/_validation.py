"""Argument checks (and :class:`AttributeDict`, the type of results with many parts) shared by
every cvkit module.

Each helper raises ``TypeError`` (wrong kind of object) or ``ValueError`` (right kind, wrong
value) with a message that names the argument and says what was expected.
"""
from __future__ import annotations

import numbers
from typing import Any

import numpy as np

BORDERS = ("zero", "replicate", "reflect", "reflect101")


_NUMERIC: dict[np.dtype, str] = {}  # dtype -> "real", "complex" or "other", worked out once per dtype


def _numeric_kind(dtype: np.dtype) -> str:
    """``"real"`` (bool, integers, floats, timedeltas), ``"complex"`` or ``"other"``: what
    :func:`as_float_array` accepts, with ``np.issubdtype``'s rules, looked up once per dtype
    (the check runs on every argument of every call)."""
    kind = _NUMERIC.get(dtype)
    if kind is None:
        if dtype == object or not (np.issubdtype(dtype, np.number) or dtype == bool):
            kind = "other"
        elif np.issubdtype(dtype, np.complexfloating):
            kind = "complex"
        else:
            kind = "real"
        _NUMERIC[dtype] = kind
    return kind


def as_float_array(value, name: str, *, ndim=None, finite: bool = True, allow_empty: bool = False) -> np.ndarray:
    """``value`` as a float64 array (a new array only when conversion needs one)."""
    if isinstance(value, (str, bytes)) or value is None:
        raise TypeError(f"{name} must be a numeric array, got {type(value).__name__}")
    array = np.asarray(value)
    kind = _numeric_kind(array.dtype)
    if kind == "other":
        raise TypeError(f"{name} must be a real numeric array, got dtype {array.dtype}")
    if kind == "complex":
        raise TypeError(f"{name} must be real, got complex dtype {array.dtype}")
    if ndim is not None:
        allowed = (ndim,) if isinstance(ndim, int) else tuple(ndim)
        if array.ndim not in allowed:
            want = " or ".join(str(n) for n in allowed)
            raise ValueError(f"{name} must have {want} dimensions, got shape {array.shape}")
    if not allow_empty and array.size == 0:
        raise ValueError(f"{name} must not be empty, got shape {array.shape}")
    # integers and booleans are finite in float64 as well: only floating input needs a look
    floating = array.dtype.kind not in "biu"
    array = array.astype(np.float64, copy=False)
    if finite and floating and not np.isfinite(array).all():
        raise ValueError(f"{name} must contain only finite values (found NaN or inf)")
    return array


def as_image(image, name: str = "image", *, color: bool = True) -> np.ndarray:
    """A grayscale ``(H, W)`` or (if ``color``) RGB ``(H, W, 3)`` image as float64."""
    array = as_float_array(image, name, ndim=(2, 3) if color else 2)
    if array.ndim == 3 and array.shape[2] != 3:
        raise ValueError(f"{name} must be (H, W) grayscale or (H, W, 3) colour, got shape {array.shape}")
    return array


def check_border(border) -> str:
    if not isinstance(border, str) or border not in BORDERS:
        raise ValueError(f"border must be one of {', '.join(map(repr, BORDERS))}, got {border!r}")
    return border


def check_int(value, name: str, *, minimum=None, odd: bool = False) -> int:
    """An integer (Python or NumPy, not bool), at least ``minimum``, optionally odd."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__} {value!r}")
    value = int(value)
    if minimum is not None and value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    if odd and value % 2 == 0:
        raise ValueError(f"{name} must be odd, got {value}")
    return value


def check_bool(value, name: str) -> bool:
    """``value`` as a ``bool``; it must be ``True`` or ``False`` (a NumPy bool too), not 0, 1 or None."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{name} must be True or False, got {type(value).__name__} {value!r}")
    return bool(value)


def check_real(value, name: str, *, positive: bool = False, nonnegative: bool = False) -> float:
    """A finite real scalar, optionally > 0 or >= 0."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, np.integer, np.floating)):
        raise TypeError(f"{name} must be a real number, got {type(value).__name__} {value!r}")
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    if positive and value <= 0:
        raise ValueError(f"{name} must be > 0, got {value}")
    if nonnegative and value < 0:
        raise ValueError(f"{name} must be >= 0, got {value}")
    return value


def as_rng(rng: "np.random.Generator | int | None") -> np.random.Generator:
    """``rng`` (a Generator, an int seed or None) as a ``numpy.random.Generator``."""
    if isinstance(rng, (numbers.Integral, np.integer)) and not isinstance(rng, bool) and rng < 0:
        raise ValueError(f"rng as an int seed must be >= 0, got {rng}")
    if rng is None or isinstance(rng, (numbers.Integral, np.integer)) and not isinstance(rng, bool):
        return np.random.default_rng(None if rng is None else int(rng))
    if isinstance(rng, np.random.Generator):
        return rng
    raise TypeError(f"rng must be a numpy.random.Generator, an int seed or None, got {type(rng).__name__}")


# ---------------------------------------------------------------------------------- bounded work
#: The most memory (bytes) one array a cvkit function allocates may take: a call that would need
#: more raises ``ValueError`` naming the argument responsible, instead of letting the kernel die.
MAX_ARRAY_BYTES = 2 * 1024**3


def check_size(value, name: str, *, minimum: int = 1, maximum: int) -> int:
    """An integer count or length in ``[minimum, maximum]`` (a documented bound of the caller)."""
    value = check_int(value, name, minimum=minimum)
    if value > maximum:
        raise ValueError(f"{name} must be <= {maximum}, got {value}")
    return value


def check_allocation(shape, name: str, *, itemsize: int = 8, what: str = "the result") -> tuple[int, ...]:
    """Raise ``ValueError`` naming ``name`` if an array of ``shape`` would exceed
    :data:`MAX_ARRAY_BYTES`; return the shape as a tuple of ints."""
    dims = tuple(int(n) for n in shape)
    nbytes = itemsize
    for n in dims:
        nbytes *= max(n, 0)
    if nbytes > MAX_ARRAY_BYTES:
        raise ValueError(
            f"{name} asks for {what} of shape {dims} ({nbytes / 1024**3:.1f} GiB), more than the "
            f"{MAX_ARRAY_BYTES / 1024**3:.0f} GiB cvkit allows for one array: choose a value of {name} "
            f"that needs less")
    return dims


#: The most elementary operations (one arithmetic operation on one array element, about a
#: nanosecond) one cvkit call may plan: about a minute of NumPy work on one core. A call whose
#: estimated cost is higher raises ``ValueError`` naming the argument responsible instead of
#: running for hours.
MAX_WORK = 2**36


def check_work(operations: int, name: str, *, what: str) -> int:
    """Raise ``ValueError`` naming ``name`` if ``what`` needs more than :data:`MAX_WORK`
    elementary operations (an estimate: whole-array element operations of the algorithm).

    The message says how many were asked for and which argument to reduce. Returns
    ``operations``.
    """
    if operations > MAX_WORK:
        raise ValueError(
            f"{name}: {what} needs about {operations:.2g} elementary operations, more than the "
            f"{MAX_WORK:.2g} (2**36, about a minute of work) cvkit allows for one call; use a smaller {name}")
    return operations


def check_padded(shape: tuple[int, ...], radius: int, name: str) -> tuple[int, ...]:
    """The image ``shape`` grown by ``radius`` pixels on both sides of its first two axes;
    ``ValueError`` naming ``name`` if that padded image would exceed :data:`MAX_ARRAY_BYTES`."""
    grown = (shape[0] + 2 * radius, shape[1] + 2 * radius) + tuple(shape[2:])
    return check_allocation(grown, name, what="a padded image")


def as_labels(y, name: str, n: int | None = None, classes: int | None = None, *,
              integral_floats: bool = False) -> np.ndarray:
    """Integer class labels ``0..classes−1`` as an int64 vector (of length ``n`` when given).

    ``integral_floats`` also takes floats that hold whole numbers (``[2.0, 0.0]``), as targets
    often arrive; fractional or non-finite values are then a ``ValueError``.
    """
    if isinstance(y, (str, bytes)) or y is None:
        raise TypeError(f"{name} must be an integer array of class labels, got {type(y).__name__}")
    arr = np.asarray(y)
    kinds = "iuf" if integral_floats else "iu"
    if arr.dtype == bool or arr.dtype.kind not in kinds:
        raise TypeError(f"{name} must be an integer array of class labels 0..C-1, got dtype {arr.dtype}")
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array of labels, got shape {arr.shape}")
    if arr.dtype.kind == "f" and (not np.all(np.isfinite(arr)) or np.any(arr != np.round(arr))):
        raise ValueError(f"{name} must hold integer class labels (found non-integer values)")
    if n is not None and arr.shape[0] != n:
        raise ValueError(f"{name} must have one label per row ({n}), got {arr.shape[0]}")
    if arr.size and arr.min() < 0:
        raise ValueError(f"{name} must contain labels >= 0, got {int(arr.min())}")
    if arr.size and (arr.max() >= 2.0 ** 63 if arr.dtype.kind == "f" else
                     arr.dtype.kind == "u" and arr.max() > np.iinfo(np.int64).max):  # beyond int64
        raise ValueError(f"{name} must contain labels below 2**63, got {int(arr.max())}")
    if classes is not None and arr.size and arr.max() >= classes:
        raise ValueError(f"{name} must contain labels < {classes} (the number of classes), got {int(arr.max())}")
    return arr.astype(np.int64)


class AttributeDict(dict):
    """A dict whose keys are also attributes (``result.rms`` is ``result["rms"]``): the base of
    results with many named parts, such as :class:`cvkit.calibration.CalibrationResult`.

    >>> AttributeDict(rms=0.5).rms
    0.5
    """

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None

    def __dir__(self) -> list[str]:
        return list(super().__dir__()) + list(self.keys())


from typing import Literal  # noqa: E402  (type aliases for the annotations of the topics)

#: The ``border`` names of :data:`BORDERS`, for type hints.
Border = Literal["zero", "replicate", "reflect", "reflect101"]
