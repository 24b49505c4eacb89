"""A safe, JSON-based encoding of test inputs and candidate outputs between processes.

The grader never unpickles anything that comes from a student's process (unpickling runs
code). Values are numbers, strings, None, tuples, lists, dicts with string keys, NumPy arrays
of numeric or boolean dtype, and NumPy random generators (their bit-generator state).
"""
from __future__ import annotations

import base64
import json
import math
from typing import Any

import numpy as np

_ARRAY_KINDS = "biuf"
MAX_BYTES = 64 * 1024 * 1024  # one value crossing the sandbox boundary


class WireError(ValueError):
    """A value that cannot (or must not) cross the process boundary."""


def encode(value: Any, _depth: int = 0) -> Any:
    """``value`` as plain JSON data (raises :class:`WireError` for unsupported types)."""
    if _depth > 32:
        raise WireError("value nested too deeply")
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return {"t": "int", "v": str(int(value))}
    if isinstance(value, (float, np.floating)):
        return {"t": "float", "v": repr(float(value))}
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray) or isinstance(value, np.generic):
        arr = np.asarray(value)
        if arr.dtype.kind not in _ARRAY_KINDS:
            raise WireError(f"array of dtype {arr.dtype} cannot be graded (numeric or bool arrays only)")
        if arr.nbytes > MAX_BYTES:
            raise WireError(f"array of {arr.nbytes} bytes is too large to grade")
        # tobytes() is C-ordered for any layout and keeps 0-d arrays 0-d
        return {"t": "nd", "dtype": arr.dtype.str, "shape": list(arr.shape),
                "scalar": isinstance(value, np.generic),
                "data": base64.b64encode(arr.tobytes(order="C")).decode("ascii")}
    if isinstance(value, tuple):
        return {"t": "tuple", "v": [encode(v, _depth + 1) for v in value]}
    if isinstance(value, list):
        return {"t": "list", "v": [encode(v, _depth + 1) for v in value]}
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise WireError("dict keys must be strings")
        return {"t": "dict", "v": {k: encode(v, _depth + 1) for k, v in value.items()}}
    if isinstance(value, np.random.Generator):
        state = value.bit_generator.state
        return {"t": "rng", "state": json.loads(json.dumps(state, default=int))}
    raise WireError(f"a value of type {type(value).__name__} cannot be graded")


def decode(data: Any, _depth: int = 0) -> Any:
    """Inverse of :func:`encode`, accepting only what :func:`encode` produces."""
    if _depth > 32:
        raise WireError("value nested too deeply")
    if data is None or isinstance(data, (bool, str)):
        return data
    if not isinstance(data, dict) or "t" not in data:
        raise WireError(f"malformed value {str(data)[:80]!r}")
    kind = data["t"]
    if kind == "int":
        return int(data["v"])
    if kind == "float":
        text = data["v"]
        if text not in ("nan", "inf", "-inf"):
            float(text)  # validates
        return float(text)
    if kind == "nd":
        dtype = np.dtype(data["dtype"])
        if dtype.kind not in _ARRAY_KINDS or dtype.hasobject:
            raise WireError(f"dtype {dtype} not allowed")
        shape = tuple(int(n) for n in data["shape"])
        raw = base64.b64decode(data["data"].encode("ascii"), validate=True)
        expected = dtype.itemsize * (math.prod(shape) if shape else 1)
        if len(raw) != expected:
            raise WireError("array data does not match its shape")
        arr = np.frombuffer(raw, dtype=dtype).reshape(shape).copy()
        return arr[()] if data.get("scalar") and arr.ndim == 0 else arr
    if kind == "tuple":
        return tuple(decode(v, _depth + 1) for v in data["v"])
    if kind == "list":
        return [decode(v, _depth + 1) for v in data["v"]]
    if kind == "dict":
        return {str(k): decode(v, _depth + 1) for k, v in data["v"].items()}
    if kind == "rng":
        state = data["state"]
        name = state.get("bit_generator")
        if name not in ("PCG64", "PCG64DXSM", "MT19937", "Philox", "SFC64"):
            raise WireError(f"bit generator {name!r} not allowed")
        bit_generator = getattr(np.random, name)()
        bit_generator.state = state
        return np.random.Generator(bit_generator)
    raise WireError(f"unknown value kind {kind!r}")


def dumps(value: Any) -> str:
    return json.dumps(encode(value))


def loads(text: str) -> Any:
    return decode(json.loads(text))
