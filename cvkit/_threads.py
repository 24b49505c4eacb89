"""BLAS on one thread, for the small networks of :mod:`cvkit.nn` and :mod:`cvkit.train`."""
from __future__ import annotations

import contextlib
from typing import Any, ContextManager

try:  # installed with scikit-learn, which the digits come from
    from threadpoolctl import threadpool_limits as _threadpool_limits
except ImportError:  # pragma: no cover
    _threadpool_limits = None

__all__ = ["single_thread"]


def single_thread() -> ContextManager[Any]:
    """BLAS limited to one thread (a no-op without ``threadpoolctl``): the matrices of a small
    network are tiny, and extra threads only add overhead and steal CPU from the rest of a busy
    machine (on a busy 2-core machine a product of 512×144 by 144×32 took 16 ms with threads
    and 0.5 ms without)."""
    return _threadpool_limits(1) if _threadpool_limits is not None else contextlib.nullcontext()
