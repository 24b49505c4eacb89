"""The algorithm registry, the course packages that add algorithms, and the providers.

Every algorithm has an id ``"<namespace>.<name>"``: cvkit's own live in the namespace of their
topic module (``"filters.gaussian"``, see ``docs/catalog.md``); an instructor's course package
adds its own under its name (``"mycourse.gamma_correction"``). A reference implementation
registers itself when its module is imported, through :func:`algorithm`, a decorator that only
records metadata: the id, the section of the notes and where its check lives. Nothing is
resolved until somebody asks (:func:`get`, :attr:`Algorithm.check`).

Course packages
---------------
An installed distribution that declares an entry point in the group ``cvkit.algorithms``::

    [project.entry-points."cvkit.algorithms"]
    mycourse = "mycourse"

adds the algorithms its module registers with ``@cvkit.algorithm("mycourse.<name>", ...)``,
with the same power as cvkit's own (reference, check with public and hidden cases, comparator,
mistakes, allowed building blocks). The entry point's name is the namespace of its ids. It is
imported on demand (``get("mycourse.gamma_correction")``, :func:`algorithms`, ``cvkit list``).
A package that fails to import, uses another namespace or registers an id that already exists is
refused and reported by :func:`package_errors`, never fatal. Its checks are validated when first
used: a check whose reference fails its own public cases is refused (:func:`validate`).

Providers
---------
A *provider* is a named set of alternative implementations of existing ids:

``reference``
    the registered reference implementations (always complete).
``student``
    functions a notebook registers with ``@student("filters.gaussian")``.
plugins
    external packages that declare an entry point in the group ``cvkit.providers``. The entry
    point loads to a mapping ``{algorithm id: callable}`` or to a function returning one.

Pipelines inside cvkit call their building blocks through :func:`implementation`, so that
``with cvkit.use("student"): cvkit.filters.gaussian(img, 2)`` runs the reference Gaussian on
top of the *student's* ``gaussian_kernel`` and falls back to the reference for anything the
provider lacks. A provider is checked against the registry as pluggy checks a hook
implementation against its specification: an unknown id or a signature that differs from the
reference's refuses the provider, with a message naming it. A plugin that fails to load is
recorded (see :func:`plugin_errors`), never fatal; an id registered twice from two different
places is a ``ValueError`` naming both.
"""
from __future__ import annotations

import contextlib
import contextvars
import copy
import difflib
import importlib
import importlib.metadata
import inspect
import pkgutil
import re
import sys
import threading
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, TypeVar

__all__ = [
    "Algorithm",
    "CoursePackage",
    "Provider",
    "algorithm",
    "algorithms",
    "get",
    "validate",
    "implementation",
    "use",
    "active_provider",
    "student",
    "provider",
    "providers",
    "register_provider",
    "plugin_errors",
    "package_errors",
    "course_packages",
    "reload_plugins",
    "reference_functions",
    "signature_differences",
    "topic_modules",
    "namespace_problem",
    "ENTRY_POINT_GROUP",
    "ALGORITHMS_GROUP",
]

ENTRY_POINT_GROUP = "cvkit.providers"
ALGORITHMS_GROUP = "cvkit.algorithms"
REFERENCE = "reference"
STUDENT = "student"
CVKIT = "cvkit"

_NAMESPACE = r"[a-z_][a-z0-9_]*"
_ID_PATTERN = re.compile(rf"^{_NAMESPACE}\.[A-Za-z_][A-Za-z0-9_]*$")
# cvkit modules that are infrastructure, not algorithm topics
_NOT_TOPICS = {"registry", "grading", "sandbox", "cli", "course", "data", "catalog", "scaffold", "_validation"}
_PACKAGE_DIR = Path(__file__).resolve().parent

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


def topic_modules() -> list[str]:
    """Names of cvkit's algorithm modules (``filters``, ``noise``, ...): the namespaces of
    cvkit's own ids, which no course package may use."""
    return list(_topics())


_topic_cache: list[tuple[str, ...]] = []


def _topics() -> tuple[str, ...]:
    if not _topic_cache:
        names = (info.name for info in pkgutil.iter_modules([str(_PACKAGE_DIR)]))
        _topic_cache.append(tuple(sorted(n for n in names if not n.startswith("_") and n not in _NOT_TOPICS)))
    return _topic_cache[0]


# --------------------------------------------------------------------------------------------
# Course packages (entry-point group cvkit.algorithms)
# --------------------------------------------------------------------------------------------
@dataclass
class CoursePackage:
    """An installed course package: an entry point of the group ``cvkit.algorithms``.

    Attributes
    ----------
    name : str
        The entry point's name: the namespace of the package's ids (``"mycourse"``).
    value : str
        The module the entry point imports (``"mycourse"``).
    distribution : str
        The distribution that declares it (its ``pip`` name).
    ids : list of str
        The algorithm ids it registered.
    error : str or None
        Why it was refused, if it was.
    """

    name: str
    value: str
    distribution: str
    ids: list = field(default_factory=list)
    error: str | None = None

    @property
    def origin(self) -> str:
        """How messages name the package: distribution and entry point."""
        return f"course package {self.distribution!r} (entry point {self.name} = {self.value})"


_loading: contextvars.ContextVar[CoursePackage | None] = contextvars.ContextVar("cvkit_loading", default=None)
_packages: dict[tuple[str, str, str], CoursePackage] = {}  # (distribution, name, value) → package


def _entry_points(group: str) -> list:
    return list(importlib.metadata.entry_points(group=group))


def _distribution(entry_point: Any) -> str:
    dist = getattr(entry_point, "dist", None)
    return str(dist.metadata["Name"]) if dist is not None else "?"


def namespace_problem(name: str) -> str | None:
    """Why ``name`` cannot be a course package's namespace (entry point name), or None."""
    if not re.fullmatch(_NAMESPACE, name):
        return (f"the namespace {name!r} (a course package's entry point name, the first part of its ids) must be "
                "lower case letters, digits and underscores (e.g. 'mycourse')")
    if name in _topics() or name in _NOT_TOPICS or name == CVKIT:
        return f"the namespace {name!r} belongs to a cvkit module: choose your course's own name (e.g. 'mycourse')"
    return None


def _forget(package: CoursePackage) -> None:
    """Unregister every algorithm of ``package`` (it was refused, or is being reloaded)."""
    for algorithm_id in [key for key, record in _algorithms.items() if record.course is package]:
        record = _algorithms.pop(algorithm_id)
        code = getattr(record.reference, "__code__", None)
        if _reference_codes.get(code) == algorithm_id:
            del _reference_codes[code]
    package.ids = []


def _load_package(entry_point: Any) -> CoursePackage:
    package = CoursePackage(entry_point.name, entry_point.value, _distribution(entry_point))
    problem = namespace_problem(package.name)
    if problem is not None:
        package.error = f"{package.origin}: refused: {problem}"
        return package
    token = _loading.set(package)
    try:
        entry_point.load()
    except Exception as exc:  # a broken package is reported, never fatal
        _forget(package)
        package.error = f"{package.origin}: {type(exc).__name__}: {exc}"
        return package
    finally:
        _loading.reset(token)
    top = package.value.partition(":")[0].split(".")[0]
    for record in _algorithms.values():  # imported before (directly): the entry point claims them
        if record.course is None and record.namespace == package.name \
                and getattr(record.reference, "__module__", "").split(".")[0] == top:
            record.course, record.package = package, package.origin
            package.ids.append(record.id)
    if not package.ids:
        package.error = (f"{package.origin}: registers no algorithm: decorate its reference implementations "
                         f"with @cvkit.algorithm('{package.name}.<name>', section=..., check=...)")
    return package


_scanned: set[str | None] = set()  # namespaces whose entry points were looked up (None: all of them)


def _load_packages(namespace: str | None = None) -> None:
    """Import the course packages (those whose entry point is ``namespace``, or all) once; the
    entry points are looked up once per namespace (again after :func:`reload_plugins`)."""
    with _lock:
        if None in _scanned or namespace in _scanned:
            return
        for entry_point in _entry_points(ALGORITHMS_GROUP):
            if namespace is not None and entry_point.name != namespace:
                continue
            key = (_distribution(entry_point), entry_point.name, entry_point.value)
            if key not in _packages:
                _packages[key] = _load_package(entry_point)
        _scanned.add(namespace)


def course_packages() -> list[CoursePackage]:
    """Every course package found (loaded, or refused with its ``error``)."""
    _load_packages()
    return sorted(_packages.values(), key=lambda p: (p.name, p.distribution))


def package_errors() -> dict[str, str]:
    """Course packages that were refused: ``{entry point name: reason}``."""
    errors: dict[str, str] = {}
    for package in course_packages():
        if package.error:
            errors[package.name] = "; ".join(filter(None, (errors.get(package.name), package.error)))
    return errors


# --------------------------------------------------------------------------------------------
# Algorithms (the reference provider)
# --------------------------------------------------------------------------------------------
@dataclass
class Algorithm:
    """What the registry knows about one algorithm id.

    Attributes
    ----------
    id : str
        The catalog id, ``"<namespace>.<name>"``.
    section : str
        The section of the course notes the algorithm comes from.
    reference : callable
        The reference implementation.
    check : cvkit.grading.Check or None
        How the algorithm is graded (resolved lazily from ``"module:attribute"``). A course
        package's check is validated when first resolved (see :func:`validate`).
    package : str
        Who registered it: ``"cvkit"`` or the course package (distribution and entry point).
    exercise : str or None
        The notebook section its exercise sits under, when not ``section``.
    """

    id: str
    section: str
    reference: Callable
    _check: Any = field(default=None, repr=False)
    package: str = CVKIT
    course: CoursePackage | None = field(default=None, repr=False)
    _refusal: str | None = field(default=None, repr=False)
    _validated: bool = field(default=False, repr=False)
    exercise: str | None = None

    @property
    def cited(self) -> str:
        """What a report cites: the section, and the exercise's own when it sits elsewhere
        (``"3.6, 3.7"``)."""
        return self.section if self.exercise in (None, self.section) else f"{self.section}, {self.exercise}"

    @property
    def module(self) -> str:
        """The namespace of the id (cvkit's topic module, or the course package's name)."""
        return self.namespace

    @property
    def namespace(self) -> str:
        return self.id.split(".", 1)[0]

    @property
    def source(self) -> str:
        return _source_of(self.reference)

    def resolve_check(self) -> Any:
        """The check, resolved from ``"module:attribute"`` if needed, without validating it."""
        spec = self._check
        if isinstance(spec, str):
            module_name, _, attr = spec.partition(":")
            spec = self._check = getattr(importlib.import_module(module_name), attr)
        return spec

    @property
    def check(self) -> Any:
        spec = self.resolve_check()
        if self.course is not None and spec is not None and not self._validated:
            problems = _reference_problems(self, spec)
            self._validated = True
            self._refusal = _refusal_message(self, problems) if problems else None
        if self._refusal is not None:
            raise ValueError(self._refusal)
        return spec

    @property
    def doc(self) -> str:
        text = (self.reference.__doc__ or "").strip()
        return text.splitlines()[0] if text else ""


_algorithms: dict[str, Algorithm] = {}
_reference_codes: dict[Any, str] = {}


def _registrant(function: Callable) -> tuple[str, CoursePackage | None]:
    package = _loading.get()
    if package is not None:
        return package.origin, package
    module = getattr(function, "__module__", None) or "?"
    top = module.split(".")[0]
    return (CVKIT if top == CVKIT else f"module {module!r}"), None


_F = TypeVar("_F", bound=Callable[..., Any])


def algorithm(algorithm_id: str, *, section: str, check: Any = None, exercise: str | None = None) -> Callable[[_F], _F]:
    """Decorator registering a reference implementation under ``algorithm_id``.

    ``section`` is the section of the course notes the algorithm comes from (the catalog's);
    ``exercise`` the notebook section its exercise sits under when that is another one (it
    needs what a neighbouring section teaches): reports then cite both.

    It records metadata only and returns the function unchanged. ``check`` is a
    :class:`cvkit.grading.Check` or a ``"module:attribute"`` string naming one (resolved on
    first use, so check modules may import the reference module without a cycle).

    In a course package (imported through its ``cvkit.algorithms`` entry point) the id must
    start with the entry point's name; an id that already exists, in cvkit or another package,
    is a ``ValueError`` naming both. Outside cvkit, the namespaces of cvkit's topic modules are
    refused.
    """
    _validate_id(algorithm_id)
    if not isinstance(section, str) or not section:
        raise ValueError(f"section must be a non-empty string such as '3.9.1', got {section!r}")
    if exercise is not None and (not isinstance(exercise, str) or not exercise):
        raise ValueError(f"exercise must be a section such as '3.7' (or None), got {exercise!r}")

    def record(function: _F) -> _F:
        if not callable(function):
            raise TypeError(f"@algorithm({algorithm_id!r}) must decorate a callable")
        package, course = _registrant(function)
        namespace = algorithm_id.split(".", 1)[0]
        if package != CVKIT and namespace in _topics():
            importlib.import_module(f"{CVKIT}.{namespace}")  # so that a clash names cvkit's function
        with _lock:
            previous = _algorithms.get(algorithm_id)
            if previous is not None and previous.source != _source_of(function):
                raise ValueError(
                    f"duplicate algorithm id {algorithm_id!r}: registered by {previous.package} "
                    f"({previous.source}) and again by {package} ({_source_of(function)})"
                )
            if course is not None and namespace != course.name:
                raise ValueError(f"{course.origin} registers {algorithm_id!r}: the ids of this package must "
                                 f"start with {course.name + '.'!r} (the name of its entry point)")
            if course is None and package != CVKIT and namespace in _topics():
                raise ValueError(f"{package} registers {algorithm_id!r}, but the namespace {namespace!r} belongs "
                                 "to cvkit: register your course's algorithms under your package's name")
            _algorithms[algorithm_id] = Algorithm(algorithm_id, section, function, check, package, course,
                                                  exercise=exercise)
            if course is not None and algorithm_id not in course.ids:
                course.ids.append(algorithm_id)
            code = getattr(function, "__code__", None)
            if code is not None:
                _reference_codes[code] = algorithm_id
        return function

    return record


def _load_namespace(namespace: str) -> None:
    if namespace in _topics():
        importlib.import_module(f"{CVKIT}.{namespace}")
    else:
        _load_packages(namespace)


def get(algorithm_id: str) -> Algorithm:
    """The :class:`Algorithm` registered under ``algorithm_id``.

    Imports ``cvkit.<module>``, or the course package whose entry point is the id's namespace,
    on demand. Raises ``KeyError`` with the closest known ids (and why a course package of that
    name was refused) when the id is unknown.
    """
    _validate_id(algorithm_id)
    record = _algorithms.get(algorithm_id)
    if record is None:
        _load_namespace(algorithm_id.split(".", 1)[0])
        record = _algorithms.get(algorithm_id)
    if record is None:
        known = [a.id for a in algorithms()]
        close = difflib.get_close_matches(algorithm_id, known, n=3)
        hint = f"; did you mean {', '.join(map(repr, close))}?" if close else ""
        refused = package_errors().get(algorithm_id.split(".", 1)[0])
        hint += f" ({refused})" if refused else ""
        raise KeyError(f"no algorithm registered as {algorithm_id!r}{hint}")
    return record


def algorithms() -> list[Algorithm]:
    """Every registered algorithm, sorted by id (imports all of cvkit's topic modules and the
    course packages)."""
    for module in _topics():
        importlib.import_module(f"{CVKIT}.{module}")
    _load_packages()
    return [_algorithms[key] for key in sorted(_algorithms)]


def reference_functions() -> dict[Any, str]:
    """Map from the code object of every reference function to its id (used by the guard)."""
    algorithms()
    return dict(_reference_codes)


# --------------------------------------------------------------------------------------------
# Validation of checks (a check's reference must pass its own public cases)
# --------------------------------------------------------------------------------------------
def _first_line(error: BaseException) -> str:
    text = str(error).strip()
    return f"{type(error).__name__}: {text.splitlines()[0] if text else ''}".rstrip(": ")


def _unchanged(before: Any, after: Any) -> bool:
    if hasattr(before, "shape") and hasattr(before, "dtype"):
        import numpy as np

        return bool(np.array_equal(before, after, equal_nan=before.dtype.kind in "fc"))
    return True


def _reference_problems(record: Algorithm, spec: Any) -> list[str]:
    """What is wrong with ``spec`` as the check of ``record``: its public cases cannot be
    built, or the reference raises on one, modifies its input, or does not reproduce its own
    output under the check's comparator."""
    try:
        cases = list(spec.public_cases())
    except Exception as error:  # noqa: BLE001 - the instructor's check: reported, never fatal
        return [f"its public cases cannot be built ({_first_line(error)})"]
    if not cases:
        return ["it has no public case (students need at least one visible case)"]
    call = getattr(spec, "call", None)

    def run(case: Any) -> tuple[Any, list]:
        args, kwargs = copy.deepcopy(tuple(case.args)), copy.deepcopy(dict(case.kwargs))
        # the reference's own warnings never reach stderr (a notebook's test cell writing there
        # is zeroed by nbgrader); `cvkit list --validate` reports them, naming the case
        with use(REFERENCE), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = call(record.reference, *args, **kwargs) if call is not None else record.reference(*args, **kwargs)
        return out, list(args) + list(kwargs.values())

    problems = []
    for index, case in enumerate(cases):
        label = f"public case {index + 1}" + (f" ({case.label})" if getattr(case, "label", "") else "")
        try:
            first, used = run(case)
            again, _ = run(case)
        except Exception as error:  # noqa: BLE001
            problems.append(f"{label}: the reference raised {_first_line(error)}")
            continue
        given = list(case.args) + list(case.kwargs.values())
        if not all(_unchanged(a, b) for a, b in zip(given, used)):
            problems.append(f"{label}: the reference modified its input")
        try:
            mismatch = spec.compare(again, first, case)
        except Exception as error:  # noqa: BLE001
            problems.append(f"{label}: the comparator raised {_first_line(error)} on the reference's output")
            continue
        if mismatch is not None:
            message = str(getattr(mismatch, "message", mismatch)).strip().splitlines()
            problems.append(f"{label}: the reference's output does not pass the check's comparator against "
                            f"itself ({message[0] if message else 'no message'})")
    return problems


def _refusal_message(record: Algorithm, problems: list[str]) -> str:
    return (f"{record.package}: the check of {record.id!r} is refused: " + "; ".join(problems)
            + f" (reference {record.source})")


def validate(algorithm_id: str) -> int:
    """Run the reference of ``algorithm_id`` on its check's public cases, as a candidate would
    be run, and refuse a check it fails.

    Parameters
    ----------
    algorithm_id : str
        An id such as ``"filters.gaussian"`` or ``"mycourse.gamma_correction"``.

    Returns
    -------
    int
        The number of public cases the reference passes.

    Raises
    ------
    ValueError
        Naming the package, when the algorithm has no check, its public cases cannot be built,
        or the reference raises on a case, modifies its input, or does not pass the check's
        comparator against its own output (e.g. a NaN the comparator refuses, a random result
        drawn outside ``rng``).
    KeyError
        When no algorithm is registered as ``algorithm_id``.
    """
    record = get(algorithm_id)
    spec = record.resolve_check()
    if spec is None:
        raise ValueError(f"{record.package}: algorithm {algorithm_id!r} has no check to validate")
    problems = _reference_problems(record, spec)
    if record.course is not None:
        record._validated, record._refusal = True, (_refusal_message(record, problems) if problems else None)
    if problems:
        raise ValueError(_refusal_message(record, problems))
    return len(spec.public_cases())


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

_POSITIONAL = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)


def _same_default(a: Any, b: Any) -> bool:
    if a is b:
        return True
    try:
        same = a == b
    except Exception:  # noqa: BLE001 - values that do not compare: not told apart
        return True
    if not isinstance(same, bool):
        return True  # arrays and the like: not told apart
    numbers = isinstance(a, (int, float)) and isinstance(b, (int, float))
    return same and (numbers or type(a) is type(b))


def _default_difference(ref: inspect.Parameter, own: inspect.Parameter) -> list[str]:
    if ref.default is ref.empty:
        return []  # a default where the reference has none is harmless: callers always pass it
    if own.default is own.empty:
        return [f"{ref.name!r} has no default (the reference's is {ref.default!r})"]
    if not _same_default(ref.default, own.default):
        return [f"{ref.name!r} defaults to {own.default!r} (the reference's to {ref.default!r})"]
    return []


def signature_differences(reference: Callable, function: Callable) -> list[str]:
    """How ``function``'s signature differs from ``reference``'s, in words (empty: compatible).

    Compatible means: the reference's positional parameters with the same names in the same
    order, its keyword-only parameters by name, a default wherever the reference has one (the
    same value), and defaults on any extra parameter. A generic wrapper taking ``*args`` and
    ``**kwargs`` is accepted as it is.
    """
    try:
        ref, own = inspect.signature(reference), inspect.signature(function)
    except (TypeError, ValueError):
        return []
    own_kinds = {p.kind for p in own.parameters.values()}
    if {inspect.Parameter.VAR_POSITIONAL, inspect.Parameter.VAR_KEYWORD} <= own_kinds:
        return []
    ref_positional = [p for p in ref.parameters.values() if p.kind in _POSITIONAL]
    own_positional = [p for p in own.parameters.values() if p.kind in _POSITIONAL]
    differences = []
    for index, expected in enumerate(ref_positional):
        if index >= len(own_positional):
            if inspect.Parameter.VAR_POSITIONAL not in own_kinds:
                differences.append(f"parameter {expected.name!r} (position {index + 1}) is missing")
            continue
        got = own_positional[index]
        if got.name != expected.name:
            differences.append(f"parameter {index + 1} is {got.name!r}, the reference's is {expected.name!r}")
            continue
        if expected.kind == expected.POSITIONAL_OR_KEYWORD and got.kind == got.POSITIONAL_ONLY:
            differences.append(f"{got.name!r} cannot be passed by keyword (the reference's can)")
        differences += _default_difference(expected, got)
    for extra in own_positional[len(ref_positional):]:
        if extra.default is extra.empty:
            differences.append(f"extra parameter {extra.name!r} has no default (the reference has no such parameter)")
    for expected in (p for p in ref.parameters.values() if p.kind == p.KEYWORD_ONLY):
        named = own.parameters.get(expected.name)
        if named is None or named.kind == named.POSITIONAL_ONLY:
            if inspect.Parameter.VAR_KEYWORD not in own_kinds:
                differences.append(f"keyword parameter {expected.name!r} is missing")
            continue
        differences += _default_difference(expected, named)
    for extra in (p for p in own.parameters.values() if p.kind == p.KEYWORD_ONLY and p.name not in ref.parameters):
        if extra.default is extra.empty:
            differences.append(f"extra keyword parameter {extra.name!r} has no default")
    return differences


def _provider_problems(implementations: Mapping[str, Callable]) -> list[str]:
    """Why a provider's implementations do not fit the registry: unknown ids, signatures that
    differ from the reference's."""
    problems = []
    for algorithm_id, function in implementations.items():
        try:
            record = get(algorithm_id)
        except (KeyError, ValueError) as error:
            problems.append(f"{algorithm_id!r} is not a registered algorithm ({error.args[0]})")
            continue
        if not callable(function):
            problems.append(f"the implementation of {algorithm_id!r} is not callable ({type(function).__name__})")
            continue
        problems += [f"{algorithm_id}: {difference}" for difference in signature_differences(record.reference, function)]
    return problems


def register_provider(name: str, implementations: Mapping[str, Callable], origin: str = "") -> Provider:
    """Register (or extend) provider ``name`` with ``{algorithm id: callable}``.

    Raises ``ValueError`` naming the provider (and ``origin``) when an id is unknown or an
    implementation's signature differs from the reference's (:func:`signature_differences`);
    nothing is registered then.
    """
    if not isinstance(name, str) or not name or name == REFERENCE:
        raise ValueError(f"provider name must be a non-empty string other than 'reference', got {name!r}")
    if not isinstance(implementations, Mapping):
        raise TypeError(
            f"implementations of provider {name!r} must be a mapping {{id: callable}}, "
            f"got {type(implementations).__name__}"
        )
    problems = _provider_problems(implementations)
    if problems:
        where = f" ({origin})" if origin else ""
        raise ValueError(f"provider {name!r}{where} refused: " + "; ".join(problems))
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
        for ep in _entry_points(ENTRY_POINT_GROUP):
            origin = f"{_distribution(ep)}: {ep.name} = {ep.value}"
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
    """Plugins of the entry-point group that failed to load or were refused: ``{name: reason}``."""
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
    """Forget and rediscover entry-point providers and course packages (for tests and
    long-lived kernels): a course package's algorithms are unregistered and its modules
    imported afresh on next use, so edits to the package take effect."""
    with _lock:
        for name in list(_providers):
            if name != STUDENT:
                del _providers[name]
        _plugin_errors.clear()
        for package in list(_packages.values()):
            _forget(package)
            top = package.value.partition(":")[0].split(".")[0]
            if top != CVKIT:
                for module in [m for m in sys.modules if m == top or m.startswith(top + ".")]:
                    del sys.modules[module]
        _packages.clear()
        _scanned.clear()
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
