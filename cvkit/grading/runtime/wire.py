"""A safe, JSON-based encoding of test inputs and candidate outputs between processes.

The grader never unpickles anything that comes from a student's process (unpickling runs
code). Values are numbers, strings, None, tuples, lists, dicts with string keys, NumPy arrays
of numeric or boolean dtype, and NumPy random generators (their bit-generator state).

:class:`BoxCall` is the one request the trusted side sends the sandbox's worker for a case.
"""
from __future__ import annotations

import base64
import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

_ARRAY_KINDS = "biuf"
MAX_BYTES = 64 * 1024 * 1024  # one value crossing the sandbox boundary
#: seconds a case may run when its check sets no limit of its own (``Check.time_limit``)
DEFAULT_TIME_LIMIT = 20.0


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


@dataclass(frozen=True)
class BoxCall:
    """One call of a student's function on one case, as the trusted side asks the sandbox for it.

    Built by the trusted grader (:mod:`cvkit.course.trusted`), sent by the session
    (:mod:`cvkit.sandbox.session`) as :meth:`to_wire`, read back by the worker
    (:mod:`cvkit.grading.runtime.worker`) with :meth:`from_wire`.
    """

    #: the name of the student's function in the notebook's namespace
    function: str
    #: the check call the case belongs to: after one of its cases does not return in time, the
    #: sandbox runs none of the others (None: the function's name)
    group: str | None = None
    args: tuple = ()
    kwargs: dict = field(default_factory=dict)
    time_limit: float = DEFAULT_TIME_LIMIT
    #: building blocks and ``"data.<loader>"`` ids the case may have computed outside (None:
    #: the data loaders only)
    allowed: tuple[str, ...] | None = None
    arg_names: tuple[str, ...] = ()
    forbidden_libraries: tuple[str, ...] = ()
    forbidden_functions: tuple[str, ...] = ()
    #: the name of the :mod:`~cvkit.grading.runtime.adapters` function that calls the
    #: candidate (``Check.call``), or None for a plain call
    adapter: str | None = None
    #: a cascade: the student's functions (name → algorithm id) the worker replaces by the
    #: building block the trusted side serves
    substitute: dict[str, str] = field(default_factory=dict)

    @property
    def check_group(self) -> str:
        """The group the call belongs to (:attr:`group`, else the function's name)."""
        return self.group if self.group is not None else self.function

    def to_wire(self) -> dict[str, Any]:
        """The call as JSON data, its inputs encoded (raises :class:`WireError` for an input
        that cannot cross)."""
        return {"function": self.function, "group": self.group,
                "args": encode(tuple(self.args)), "kwargs": encode(dict(self.kwargs)),
                "time_limit": self.time_limit, "allowed": None if self.allowed is None else list(self.allowed),
                "arg_names": list(self.arg_names), "forbidden_libraries": list(self.forbidden_libraries),
                "forbidden_functions": list(self.forbidden_functions), "call": self.adapter,
                "substitute": dict(self.substitute)}

    @classmethod
    def from_wire(cls, data: dict[str, Any]) -> "BoxCall":
        """Inverse of :meth:`to_wire` (raises :class:`WireError` for inputs :func:`decode` refuses)."""
        allowed = data.get("allowed")
        return cls(
            function=str(data["function"]), group=data.get("group"),
            args=decode(data["args"]), kwargs=decode(data["kwargs"]),
            time_limit=float(data.get("time_limit", DEFAULT_TIME_LIMIT)),
            allowed=None if allowed is None else tuple(allowed),
            arg_names=tuple(data.get("arg_names", ())),
            forbidden_libraries=tuple(data.get("forbidden_libraries", ())),
            forbidden_functions=tuple(data.get("forbidden_functions", ())),
            adapter=data.get("call") or None, substitute=dict(data.get("substitute") or {}),
        )
