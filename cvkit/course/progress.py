"""Progress of the course's long steps: one :class:`Phase` per phase (build, grade, record,
feedback, exports, similarity), each with a count and an estimate of the time left.

On a terminal, a phase is a tqdm bar on standard output (never standard error, where a log
reader would take it for an error). Elsewhere (a log file, a pipe, CI), each phase prints one
line when it ends: what it did, how many, in how long.
"""
from __future__ import annotations

import sys
import time
from typing import IO, Any, Iterable, Iterator

__all__ = ["Phase", "progress"]


class Phase:
    """One phase of a long command, counted in ``unit``\\ s.

    Parameters
    ----------
    name : str
        What the phase does (``"grade"``, ``"feedback"``); its bar's label.
    total : int
        How many steps it has (an estimate may be corrected, :meth:`set_total`).
    enabled : bool
        False: silent (every method does nothing).
    unit : str
        What a step is (``"submission"``, ``"page"``).
    stream : file, optional
        Where to write (default standard output).
    position : int, optional
        The bar's line among bars shown at once (terminal only).

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> with Phase("export", 2, unit="file", stream=out) as phase:
    ...     phase.update(2)
    >>> out.getvalue().startswith("export: 2/2 files in ")
    True
    """

    def __init__(self, name: str, total: int, enabled: bool = True, *, unit: str = "job",
                 stream: IO[str] | None = None, position: int | None = None) -> None:
        self.name, self.total, self.enabled, self.unit = name, int(total), bool(enabled), unit
        self.done = 0
        self.start = time.perf_counter()
        self.stream = stream if stream is not None else sys.stdout
        self._bar: Any = None
        self._closed = False
        if self.enabled and _is_terminal(self.stream):
            try:
                from tqdm import tqdm
            except ImportError:  # pragma: no cover - tqdm comes with cvkit[course]
                tqdm = None
            if tqdm is not None:
                self._bar = tqdm(desc=name, total=self.total, unit=unit, file=self.stream, position=position,
                                 dynamic_ncols=True, leave=True, mininterval=0.5)

    def __enter__(self) -> Phase:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def update(self, n: int = 1) -> None:
        """``n`` more steps done."""
        self.done += n
        if self._bar is not None:
            self._bar.update(n)

    def set_total(self, total: int) -> None:
        """The number of steps, once better known than at the start."""
        self.total = int(total)
        if self._bar is not None:
            self._bar.total = self.total
            self._bar.refresh()

    def describe(self, text: str) -> None:
        """Say what the phase is doing now (terminal only, e.g. the chapter being built)."""
        if self._bar is not None:
            self._bar.set_description_str(text)

    def close(self) -> None:
        """End the phase: the bar stays at its final count; elsewhere, one line says what was done."""
        if self._closed or not self.enabled:
            return
        self._closed = True
        if self._bar is not None:
            self._bar.set_description_str(self.name)
            self._bar.close()
            return
        plural = "" if self.total == 1 else "s"
        self.stream.write(f"{self.name}: {self.done}/{self.total} {self.unit}{plural} "
                          f"in {time.perf_counter() - self.start:.0f} s\n")
        self.stream.flush()


def _is_terminal(stream: IO[str]) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def progress(iterable: Iterable[Any], desc: str, enabled: bool, total: int | None = None,
             unit: str = "job") -> Iterator[Any]:
    """Iterate over ``iterable`` as one :class:`Phase` named ``desc``.

    Parameters
    ----------
    iterable : iterable
        What to iterate over.
    desc : str
        The phase's name.
    enabled : bool
        False: no progress shown.
    total : int, optional
        Number of items (default ``len(iterable)``).
    unit : str
        What an item is.

    Yields
    ------
    object
        The items of ``iterable``.
    """
    items = list(iterable)
    with Phase(desc, len(items) if total is None else total, enabled, unit=unit) as phase:
        for item in items:
            yield item
            phase.update()
