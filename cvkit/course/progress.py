"""Progress bars of the course's long steps (build, autograde), on stderr."""
from __future__ import annotations

import sys
from typing import Any, Iterable


def progress(iterable: Iterable[Any] | None, desc: str, enabled: bool, total: int | None = None) -> Any:
    """A tqdm progress bar over ``iterable`` (a manual bar when ``iterable`` is None).

    Parameters
    ----------
    iterable : iterable or None
        What to iterate over; None for a bar advanced by hand (``bar.update(n)``).
    desc : str
        The bar's label.
    enabled : bool
        False: ``iterable`` itself is returned (None for a manual bar).
    total : int, optional
        Number of steps of a manual bar.

    Returns
    -------
    tqdm or iterable or None
        The bar, or ``iterable`` when bars are off or tqdm is not installed.
    """
    if not enabled:
        return iterable
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover
        return iterable
    return tqdm(iterable, desc=desc, total=total, unit="job", file=sys.stderr)
