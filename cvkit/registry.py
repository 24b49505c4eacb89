"""The algorithm registry and the providers that implement algorithms.

Every algorithm of the course has an id from CATALOG.md (``"filters.gaussian"``). Its reference
implementation registers itself when its module is imported, through :func:`algorithm`, a
decorator that only records metadata: the id, the seed section and where its check lives.
Nothing is resolved until somebody asks (:func:`get`, :attr:`Algorithm.check`).

Providers
---------
A *provider* is a named set of implementations:

``reference``
    cvkit's own functions (always complete).
``student``
    functions a notebook registers with ``@student("filters.gaussian")``.
plugins
    external packages that declare an entry point in the group ``cvkit.providers``. The entry
    point loads to a mapping ``{algorithm id: callable}`` or to a function returning one.

Pipelines inside cvkit call their building blocks through :func:`implementation`, so that
``with cvkit.use("student"): cvkit.filters.gaussian(img, 2)`` runs the reference Gaussian on
top of the *student's* ``gaussian_kernel`` and falls back to the reference for anything the
provider lacks. A plugin that fails to import is recorded (see :func:`plugin_errors`), never
fatal; an id registered twice from two different places is a ``ValueError`` naming both.
"""
from __future__ import annotations

import contextlib
import contextvars
import difflib
import importlib
import importlib.metadata
import pkgutil
import re
import threading
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Mapping

__all__ = [
    "Algorithm",
    "Provider",
    "algorithm",
    "algorithms",
    "get",
    "implementation",
    "use",
    "active_provider",
    "student",
    "provider",
    "providers",
    "register_provider",
    "plugin_errors",
    "reference_functions",
    "ENTRY_POINT_GROUP",
]

ENTRY_POINT_GROUP = "cvkit.providers"
REFERENCE = "reference"
STUDENT = "student"

_ID_PATTERN = re.compile(r"^[a-z_]+\.[A-Za-z_][A-Za-z0-9_]*$")
# cvkit subpackages that are infrastructure, not algorithm topics
_NOT_TOPICS = {"registry", "grading", "cli", "course", "data", "_validation", "_display"}

_lock = threading.RLock()


def _source_of(obj: Any) -> str:
    module = getattr(obj, "__module__", None) or "?"
    name = getattr(obj, "__qualname__", None) or getattr(obj, "__name__", None) or repr(obj)
    return f"{module}.{name}"


def _validate_id(algorithm_id: str) -> str:
    if not isinstance(algorithm_id, str) or not _ID_PATTERN.match(algorithm_id):
        raise ValueError(
            f"algorithm id must look like '<module>.<name>' (e.g. 'filters.gaussian'), "
            f"got {algorithm_id!r}"
        )
    return algorithm_id


# --------------------------------------------------------------------------------------------
# Algorithms (the reference provider)
# --------------------------------------------------------------------------------------------
@dataclass
class Algorithm:
    """What the registry knows about one algorithm id.

    Attributes
    ----------
    id : str
        The catalog id, ``"<module>.<name>"``.
    section : str
        The section of the course notes the algorithm comes from.
    reference : callable
        cvkit's reference implementation.
    check : cvkit.grading.Check or None
        How the algorithm is graded (resolved lazily from ``"module:attribute"``).
    """

    id: str
    section: str
    reference: Callable
    _check: Any = field(default=None, repr=False)

    @property
    def module(self) -> str:
        return self.id.split(".", 1)[0]

    @property
    def source(self) -> str:
        return _source_of(self.reference)

    @property
    def check(self):
        spec = self._check
        if isinstance(spec, str):
            module_name, _, attr = spec.partition(":")
            resolved = getattr(importlib.import_module(module_name), attr)
            self._check = resolved
            return resolved
        return spec

    @property
    def doc(self) -> str:
        text = (self.reference.__doc__ or "").strip()
        return text.splitlines()[0] if text else ""


_algorithms: dict[str, Algorithm] = {}
_reference_codes: dict[Any, str] = {}


def algorithm(algorithm_id: str, *, section: str, check: Any = None) -> Callable:
    """Decorator registering a reference implementation under ``algorithm_id``.

    It records metadata only and returns the function unchanged. ``check`` is a
    :class:`cvkit.grading.Check` or a ``"module:attribute"`` string naming one (resolved on
    first use, so check modules may import the reference module without a cycle).
    """
    _validate_id(algorithm_id)
    if not isinstance(section, str) or not section:
        raise ValueError(f"section must be a non-empty string such as '3.9.1', got {section!r}")

    def record(function: Callable) -> Callable:
        if not callable(function):
            raise TypeError(f"@algorithm({algorithm_id!r}) must decorate a callable")
        with _lock:
            previous = _algorithms.get(algorithm_id)
            if previous is not None and previous.source != _source_of(function):
                raise ValueError(
                    f"duplicate algorithm id {algorithm_id!r}: registered by {previous.source} "
                    f"and again by {_source_of(function)}"
                )
            _algorithms[algorithm_id] = Algorithm(algorithm_id, section, function, check)
            code = getattr(function, "__code__", None)
            if code is not None:
                _reference_codes[code] = algorithm_id
        return function

    return record


def topic_modules() -> list[str]:
    """Names of cvkit's algorithm modules (``filters``, ``noise``, ...)."""
    import cvkit

    names = []
    for info in pkgutil.iter_modules(cvkit.__path__):
        if info.name.startswith("_") or info.name in _NOT_TOPICS:
            continue
        names.append(info.name)
    return sorted(names)


def _load_topic(module: str) -> None:
    if module in topic_modules():
        importlib.import_module(f"cvkit.{module}")


def get(algorithm_id: str) -> Algorithm:
    """The :class:`Algorithm` registered under ``algorithm_id``.

    Imports ``cvkit.<module>`` on demand. Raises ``KeyError`` with the closest known ids when
    the id is unknown.
    """
    _validate_id(algorithm_id)
    record = _algorithms.get(algorithm_id)
    if record is None:
        _load_topic(algorithm_id.split(".", 1)[0])
        record = _algorithms.get(algorithm_id)
    if record is None:
        known = [a.id for a in algorithms()]
        close = difflib.get_close_matches(algorithm_id, known, n=3)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        raise KeyError(f"no algorithm registered as {algorithm_id!r}{hint}")
    return record


def algorithms() -> list[Algorithm]:
    """Every registered algorithm, sorted by id (imports all of cvkit's topic modules)."""
    for module in topic_modules():
        importlib.import_module(f"cvkit.{module}")
    return [_algorithms[key] for key in sorted(_algorithms)]


def reference_functions() -> dict[Any, str]:
    """Map from the code object of every reference function to its id (used by the guard)."""
    algorithms()
    return dict(_reference_codes)


# --------------------------------------------------------------------------------------------
# Providers
# --------------------------------------------------------------------------------------------
@dataclass
class Provider:
    """A named set of implementations ``{algorithm id: callable}``."""

    name: str
    functions: dict[str, Callable] = field(default_factory=dict)
    sources: dict[str, str] = field(default_factory=dict)
    origin: str = ""

    def add(self, algorithm_id: str, function: Callable, source: str | None = None) -> None:
        _validate_id(algorithm_id)
        if not callable(function):
            raise TypeError(
                f"provider {self.name!r}: implementation of {algorithm_id!r} must be callable, "
                f"got {type(function).__name__}"
            )
        source = source or _source_of(function)
        with _lock:
            previous = self.sources.get(algorithm_id)
            if previous is not None and previous != source:
                raise ValueError(
                    f"duplicate implementation of {algorithm_id!r} in provider {self.name!r}: "
                    f"{previous} and {source}"
                )
            self.functions[algorithm_id] = function
            self.sources[algorithm_id] = source

    def remove(self, algorithm_id: str) -> None:
        self.functions.pop(algorithm_id, None)
        self.sources.pop(algorithm_id, None)

    def clear(self) -> None:
        self.functions.clear()
        self.sources.clear()

    def __contains__(self, algorithm_id: str) -> bool:
        return algorithm_id in self.functions


_providers: dict[str, Provider] = {STUDENT: Provider(STUDENT, origin="notebook")}
_plugin_errors: dict[str, str] = {}
_plugins_loaded = False


def register_provider(name: str, implementations: Mapping[str, Callable], origin: str = "") -> Provider:
    """Register (or extend) provider ``name`` with ``{algorithm id: callable}``."""
    if not isinstance(name, str) or not name or name == REFERENCE:
        raise ValueError(f"provider name must be a non-empty string other than 'reference', got {name!r}")
    if not isinstance(implementations, Mapping):
        raise TypeError(
            f"implementations of provider {name!r} must be a mapping {{id: callable}}, "
            f"got {type(implementations).__name__}"
        )
    with _lock:
        prov = _providers.setdefault(name, Provider(name, origin=origin))
        for algorithm_id, function in implementations.items():
            prov.add(algorithm_id, function, source=f"{origin or name}:{_source_of(function)}")
    return prov


def _load_plugins(reload: bool = False) -> None:
    """Discover entry points of the group ``cvkit.providers`` (once, or again with reload)."""
    global _plugins_loaded
    with _lock:
        if _plugins_loaded and not reload:
            return
        _plugins_loaded = True
        eps = importlib.metadata.entry_points()
        group = eps.select(group=ENTRY_POINT_GROUP) if hasattr(eps, "select") else eps.get(ENTRY_POINT_GROUP, [])
        for ep in group:
            origin = f"{ep.name} = {ep.value}"
            dist = getattr(ep, "dist", None)
            if dist is not None:
                origin = f"{dist.metadata['Name']}: {origin}"
            try:
                loaded = ep.load()
                mapping = loaded() if callable(loaded) and not isinstance(loaded, Mapping) else loaded
                if not isinstance(mapping, Mapping):
                    raise TypeError(f"entry point must give a mapping {{id: callable}}, got {type(mapping).__name__}")
                for algorithm_id in mapping:
                    _validate_id(algorithm_id)
                register_provider(ep.name, mapping, origin=origin)
                _plugin_errors.pop(ep.name, None)
            except Exception as exc:  # a broken plugin is reported, never fatal
                _plugin_errors[ep.name] = f"{origin}: {type(exc).__name__}: {exc}"


def plugin_errors() -> dict[str, str]:
    """Plugins of the entry-point group that failed to load: ``{name: reason}``."""
    _load_plugins()
    return dict(_plugin_errors)


def providers() -> list[str]:
    """Names of the available providers (``reference`` first)."""
    _load_plugins()
    return [REFERENCE] + sorted(_providers)


def provider(name: str) -> Provider:
    """The provider called ``name`` (``KeyError`` explaining a broken plugin)."""
    _load_plugins()
    if name in _providers:
        return _providers[name]
    if name in _plugin_errors:
        raise KeyError(f"provider {name!r} failed to load: {_plugin_errors[name]}")
    raise KeyError(f"no provider called {name!r}; available: {', '.join(providers())}")


def reload_plugins() -> None:
    """Forget and rediscover entry-point providers (for tests and long-lived kernels)."""
    with _lock:
        for name in list(_providers):
            if name != STUDENT:
                del _providers[name]
        _plugin_errors.clear()
        _load_plugins(reload=True)


def student(algorithm_id: str) -> Callable:
    """Decorator for notebooks: register a function as the student's version of an algorithm.

    Redefining the function (re-running the cell) replaces it; the function is returned
    unchanged.

    >>> @student("filters.mean_kernel")
    ... def mean_kernel(size):
    ...     ...
    """
    _validate_id(algorithm_id)

    def record(function: Callable) -> Callable:
        prov = _providers[STUDENT]
        prov.remove(algorithm_id)  # re-running a notebook cell is not a duplicate
        prov.add(algorithm_id, function)
        return function

    return record


_active: contextvars.ContextVar[str] = contextvars.ContextVar("cvkit_provider", default=REFERENCE)


def active_provider() -> str:
    """Name of the provider pipelines currently call."""
    return _active.get()


@contextlib.contextmanager
def use(name: str) -> Iterator[Provider | None]:
    """Make cvkit's pipelines call provider ``name``'s building blocks inside the block.

    Algorithms the provider does not implement fall back to the reference.

    >>> import cvkit
    >>> with cvkit.use("reference"):
    ...     pass
    """
    if not isinstance(name, str):
        raise TypeError(f"provider name must be a string, got {type(name).__name__}")
    prov = None if name == REFERENCE else provider(name)
    token = _active.set(name)
    try:
        yield prov
    finally:
        _active.reset(token)


def implementation(algorithm_id: str) -> Callable:
    """The callable pipelines should use for ``algorithm_id`` under the active provider."""
    name = _active.get()
    if name != REFERENCE:
        prov = _providers.get(name)
        if prov is not None:
            function = prov.functions.get(algorithm_id)
            if function is not None:
                return function
    return get(algorithm_id).reference
