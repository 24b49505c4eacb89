"""The one harness of the ``test_checks_*`` files: is a check complete, are its hidden cases
reproducible, do the reference and correct alternatives pass, does a stub score 0, does every
mistake fail and get named.

Every function takes what differs between chapters (seeds, thresholds, allowed building
blocks, how to fingerprint a case) as an argument; none has a chapter's value built in. The
tests every chapter owes are written once, in :class:`MistakeBankChecks` and
:class:`ChapterChecks`: a chapter's file subclasses one of them (``class TestChapterNN``) and
sets what differs as class attributes.
``tests/`` is not a package: import this module as the test files import ``alternatives_chNN``.
"""
from __future__ import annotations

import contextlib
import copy
import dataclasses
import hashlib
import pickle
import time
from unittest import mock

import numpy as np

from cvkit import registry
from cvkit.grading import Check, engine, evaluate

BORDERS = frozenset({"zero", "replicate", "reflect", "reflect101"})
#: the seeds of the hidden cases every chapter's checks are tested on
SEEDS = (101, 202, 303)
#: every registered algorithm id: the building blocks a mistake may call in most chapters
EVERY_ID = tuple(a.id for a in registry.algorithms())


# --------------------------------------------------------------------------------------------
# looking things up
# --------------------------------------------------------------------------------------------
def check_of(algorithm_id):
    """The check registered for ``algorithm_id``."""
    return registry.get(algorithm_id).check


def reference_of(algorithm_id):
    """The reference implementation registered for ``algorithm_id``."""
    return registry.get(algorithm_id).reference


def hidden_cases(algorithm_id, seed):
    """The hidden cases of ``algorithm_id`` drawn from ``default_rng(seed)``."""
    return check_of(algorithm_id).hidden_cases(np.random.default_rng(seed))


def mistakes_of(algorithm_ids):
    """``[(algorithm id, mistake name), ...]`` over the mistake banks of ``algorithm_ids``."""
    return [(aid, m.name) for aid in algorithm_ids for m in check_of(aid).mistakes]


def pair_ids(pairs):
    """Test ids ``"id:name"`` for ``(algorithm id, name)`` pairs."""
    return [f"{a}:{n}" for a, n in pairs]


def function_ids(pairs):
    """Test ids ``"id:function name"`` for ``(algorithm id, function)`` pairs."""
    return [f"{a}:{f.__name__}" for a, f in pairs]


def allowing(spec, allowed):
    """``spec`` with its allowed building blocks replaced by ``allowed``."""
    return dataclasses.replace(spec, allowed=tuple(allowed))


def allowing_itself(spec, algorithm_id):
    """``spec`` that also allows calling ``algorithm_id`` itself: graded through a ``call``
    adapter, the guard sees the adapter (not the candidate) as the student's code, so the
    reference graded as a candidate would count as calling the reference."""
    return allowing(spec, tuple(spec.allowed) + (algorithm_id,))


# --------------------------------------------------------------------------------------------
# grading
# --------------------------------------------------------------------------------------------
class _Outputs:
    """The reference's and the bank's mistakes' outputs by (function, case), for this test
    process. Grading a mistake as a candidate runs the whole bank on every failing case to
    name it, and the tests grade every mistake of a bank on the same cases: the same
    deterministic calls (on deep copies of the case) again and again. Only the *known* outputs
    the candidate is compared with are reused — the candidate itself always runs — and only
    calls that took at least ``SLOW`` seconds are kept (the rest are cheaper to repeat)."""

    SLOW = 0.002

    def __init__(self):
        self.kept = {}
        self.reference_output = engine._reference_output
        self.mistake_output = engine._mistake_output

    @staticmethod
    def _key(function, case, call):
        try:
            data = pickle.dumps((case.args, case.kwargs), protocol=5)
        except Exception:  # noqa: BLE001 - a case that cannot be pickled is simply not kept
            return None
        return function, call, hashlib.sha1(data).hexdigest()  # the functions themselves: no id reused

    def _kept(self, key, compute):
        if key is not None and key in self.kept:
            return copy.deepcopy(self.kept[key])
        start = time.perf_counter()
        value = compute()
        if key is not None and time.perf_counter() - start >= self.SLOW:
            self.kept[key] = copy.deepcopy(value)
        return value

    def reference(self, function, case, call=None):
        return self._kept(self._key(function, case, call), lambda: self.reference_output(function, case, call))

    def mistake(self, mistake, case, call=None):
        return self._kept(self._key(mistake.function, case, call), lambda: self.mistake_output(mistake, case, call))


_OUTPUTS = _Outputs()


class _Draws:
    """The hidden cases of a check by (case generator, starting state of the generator's
    random numbers), for this test process: every mistake of a bank is graded on the same
    seeds, and drawing some cases is slow (the calibration chapter renders chessboards). A
    draw is a deterministic function of the two, so a kept draw is the same cases; each use
    gets its own deep copy. Only draws that took at least ``SLOW`` seconds are kept."""

    SLOW = 0.002

    def __init__(self):
        self.kept = {}
        self.draw = Check.hidden_cases

    def __call__(self, spec, rng):
        key = (spec.hidden, repr(rng.bit_generator.state))
        if key in self.kept:
            return copy.deepcopy(self.kept[key])
        start = time.perf_counter()
        cases = self.draw(spec, rng)
        if time.perf_counter() - start >= self.SLOW:
            self.kept[key] = copy.deepcopy(cases)
        return cases


_DRAWS = _Draws()


@contextlib.contextmanager
def reusing_known_outputs():
    """Within: the engine reuses the reference's and the mistakes' slow outputs (:class:`_Outputs`)
    and the slow draws of hidden cases (:class:`_Draws`)."""
    with mock.patch.object(engine, "_reference_output", _OUTPUTS.reference), \
            mock.patch.object(engine, "_mistake_output", _OUTPUTS.mistake), \
            mock.patch.object(Check, "hidden_cases", lambda spec, rng: _DRAWS(spec, rng)):
        yield


def grade_everywhere(algorithm_id, candidate, seeds, check=None, allowed=None):
    """Reports of ``candidate`` on the public cases, then on the hidden cases of each seed.

    ``allowed`` (if given) replaces the allowed building blocks of ``check`` (or of the
    registered check)."""
    if allowed is not None:
        check = allowing(check if check is not None else check_of(algorithm_id), allowed)
    with reusing_known_outputs():
        reports = [evaluate(algorithm_id, candidate, check=check)]
        reports += [evaluate(algorithm_id, candidate, hidden=True, seed=s, check=check) for s in seeds]
    return reports


def assert_passes_everywhere(algorithm_id, candidate, seeds, check=None, allowed=None):
    """``candidate`` passes the public cases and the hidden cases of every seed."""
    for report in grade_everywhere(algorithm_id, candidate, seeds, check=check, allowed=allowed):
        assert report.passed, report.text()


def assert_reference_passes(algorithm_id, seeds, check=None):
    """The reference passes everywhere and no mistake is named."""
    for report in grade_everywhere(algorithm_id, reference_of(algorithm_id), seeds, check=check):
        assert report.passed, report.text()
        assert report.mistake is None


def raising_stub(*args, **kwargs):
    """A released, unanswered exercise."""
    raise NotImplementedError


def assert_stub_scores_zero(algorithm_id, seeds, stub=raising_stub, message="not implemented"):
    """``stub`` scores 0 everywhere; the first case says ``message`` (``None``: not checked)."""
    for report in grade_everywhere(algorithm_id, stub, seeds):
        assert report.score == 0.0
        if message is not None:
            assert message in report.cases[0].message, report.cases[0].message


def assert_scores_zero(algorithm_id, candidate, words, *, every_case=False, **evaluate_kwargs):
    """``candidate`` scores 0 and the message of its first case (``every_case``: of every case)
    says ``words``. Returns the report."""
    report = evaluate(algorithm_id, candidate, **evaluate_kwargs)
    assert report.score == 0.0, report.text()
    for case in report.cases if every_case else report.cases[:1]:
        assert words in case.message, report.text()
    return report


def assert_only_the_library_fails(algorithm_id, candidate, library):
    """``candidate`` scores 0 and every case names the forbidden ``library``, yet the same
    function passes once ``library`` is allowed: only the forbidden call fails it."""
    assert_scores_zero(algorithm_id, candidate, library, every_case=True)
    open_check = dataclasses.replace(check_of(algorithm_id), allowed_libraries=(library,))
    assert evaluate(algorithm_id, candidate, check=open_check).passed


def assert_ids_are_the_module(ids, module):
    """``ids`` are exactly the registered algorithms of ``module``: each has a check here."""
    assert sorted(a.id for a in registry.algorithms() if a.module == module) == sorted(ids)


def _named_wrongly(report, name):
    return (f"named {report.mistake!r} instead of {name!r}; per case: "
            + str([(c.label, c.mistake) for c in report.cases if not c.passed]))


def assert_mistake_fails_and_is_named(algorithm_id, name, seeds, allowed=None, *,
                                      named_on_public=True, hint=True):
    """Mistake ``name`` of ``algorithm_id``, graded as a candidate, fails the public cases and
    the hidden cases of every seed, and the hidden reports name it.

    ``allowed``: the building blocks the mistake may call (``None``: the check as registered).
    ``named_on_public``: the public report must name it too. ``hint``: the hidden reports
    carry the mistake's hint."""
    spec = check_of(algorithm_id)
    mistake = spec.mistake(name)
    check = spec if allowed is None else allowing(spec, allowed)
    with reusing_known_outputs():
        public = evaluate(algorithm_id, mistake.function, check=check)
    assert not public.passed, f"the public cases do not catch {name!r}"
    if named_on_public:
        assert public.mistake == name, "public cases: " + _named_wrongly(public, name)
    for seed in seeds:
        with reusing_known_outputs():
            report = evaluate(algorithm_id, mistake.function, hidden=True, seed=seed, check=check)
        assert not report.passed, f"hidden cases (seed {seed}) do not catch {name!r}"
        assert report.mistake == name, f"seed {seed}: " + _named_wrongly(report, name)
        if hint:
            assert report.hint == mistake.hint


# --------------------------------------------------------------------------------------------
# the shape of a check
# --------------------------------------------------------------------------------------------
def assert_check_is_complete(spec, seeds, *, public=(1, 6), hidden=(8, 14), min_mistakes=4,
                             max_name_length=70):
    """Public and hidden case counts within bounds (inclusive), every case labelled, at least
    ``min_mistakes`` mistakes with unique names of at most ``max_name_length`` characters, a
    hint and a function."""
    public_cases = spec.public_cases()
    assert public[0] <= len(public_cases) <= public[1], len(public_cases)
    assert len(spec.mistakes) >= min_mistakes, [m.name for m in spec.mistakes]
    assert len({m.name for m in spec.mistakes}) == len(spec.mistakes)
    for m in spec.mistakes:
        assert m.name and len(m.name) <= max_name_length and m.hint and callable(m.function), m.name
    for seed in seeds:
        hidden_cases = spec.hidden_cases(np.random.default_rng(seed))
        assert hidden[0] <= len(hidden_cases) <= hidden[1], len(hidden_cases)
        assert all(case.label for case in public_cases + hidden_cases)


def _same(x, y, equal_nan):
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        x, y = np.asarray(x), np.asarray(y)
        return x.shape == y.shape and np.array_equal(x, y, equal_nan=equal_nan)
    if isinstance(x, (list, tuple)) and isinstance(y, (list, tuple)):
        return len(x) == len(y) and all(_same(a, b, equal_nan) for a, b in zip(x, y))
    return type(x) is type(y) and x == y


def assert_hidden_cases_reproducible(spec, fingerprint, *, varies=None, seeds=(7, 8), equal_nan=False):
    """The hidden cases drawn twice from ``seeds[0]`` have equal fingerprints (case by case),
    and some case drawn from ``seeds[1]`` differs from the case at the same place.

    ``fingerprint(case)`` is a tuple of strings, numbers and arrays (arrays compare with
    ``np.array_equal``); ``varies(case)`` (default: ``fingerprint``) is what must change with
    the seed."""
    varies = fingerprint if varies is None else varies
    first, again, other = (spec.hidden_cases(np.random.default_rng(s)) for s in (seeds[0], seeds[0], seeds[1]))
    assert len(first) == len(again)
    for a, b in zip(first, again):
        assert _same(fingerprint(a), fingerprint(b), equal_nan), f"not reproducible: {a.label}"
    assert any(not _same(varies(a), varies(b), equal_nan) for a, b in zip(first, other)), \
        "the hidden cases do not depend on the seed"


def describe_and_array_args(case):
    """A case's description and its positional array arguments."""
    return (case.describe(), *(x for x in case.args if isinstance(x, np.ndarray)))


def describe_and_arrays(case):
    """A case's description and its array arguments, positional and keyword."""
    values = list(case.args) + list(case.kwargs.values())
    return (case.describe(), *(x for x in values if isinstance(x, np.ndarray)))


def assert_hidden_cases_use_every_border(spec, seeds, borders=BORDERS, default="reflect101"):
    """The hidden cases of every seed use exactly ``borders`` (``default`` when no ``border=``
    is given). Returns ``{seed: cases}`` for further checks."""
    drawn = {}
    for seed in seeds:
        cases = spec.hidden_cases(np.random.default_rng(seed))
        assert {case.kwargs.get("border", default) for case in cases} == set(borders)
        drawn[seed] = cases
    return drawn


# --------------------------------------------------------------------------------------------
# the tests every chapter owes, written once
# --------------------------------------------------------------------------------------------
class MistakeBankChecks:
    """The tests every mistake bank owes: each check of ``IDS`` is complete, a stub scores 0
    everywhere, and every mistake of every bank fails (public and hidden cases) and is named.

    Mistake functions are built on the reference implementations (they run under the reference
    provider when the grader compares outputs), so to grade a mistake *as a candidate* the tests
    allow the building blocks ``MISTAKES_MAY_CALL`` (``None``: the check as registered); the
    guard itself is tested by each chapter's own tests on the checks as registered.

    Subclass it in a test file as ``class TestChapterNN(MistakeBankChecks)`` with the class
    attributes below; pytest collects the inherited tests once per subclass, parametrised by
    :meth:`pytest_generate_tests` over that subclass's ids and mistakes.
    """

    #: the algorithm ids of the chapter
    IDS: tuple = ()
    SEEDS = SEEDS
    #: the building blocks a mistake graded as a candidate may call (``None``: the check as
    #: registered; unset: the chapter's own ``IDS``)
    MISTAKES_MAY_CALL: tuple | None
    #: the fewest mistakes a bank may have; ``TRIVIAL`` ids (the simplest exercises) may have one fewer
    MIN_MISTAKES = 4
    TRIVIAL: frozenset = frozenset()
    MAX_NAME_LENGTH = 70

    #: test name -> what it is parametrised over (a method of the instance, by name)
    _PARAMETERS = {
        "test_check_is_complete": "_ids",
        "test_stub_scores_zero": "_ids",
        "test_mistake_fails_and_is_named": "_mistakes",
    }

    def pytest_generate_tests(self, metafunc):
        assert self.IDS, f"{type(self).__name__} names no IDS: its tests would test nothing"
        source = self._PARAMETERS.get(metafunc.function.__name__)
        if source is not None:
            argnames, values, ids = getattr(self, source)()
            metafunc.parametrize(argnames, values, ids=ids)

    def _ids(self):
        return "algorithm_id", list(self.IDS), None

    def _mistakes(self):
        pairs = mistakes_of(self.IDS)
        return ("algorithm_id", "name"), pairs, pair_ids(pairs)

    def stub(self, algorithm_id):
        """The released, unanswered exercise of ``algorithm_id``."""
        return raising_stub

    def test_check_is_complete(self, algorithm_id):
        minimum = self.MIN_MISTAKES - 1 if algorithm_id in self.TRIVIAL else self.MIN_MISTAKES
        assert_check_is_complete(check_of(algorithm_id), self.SEEDS, public=(1, 6), hidden=(8, 14),
                                 min_mistakes=minimum, max_name_length=self.MAX_NAME_LENGTH)

    def test_stub_scores_zero(self, algorithm_id):
        assert_stub_scores_zero(algorithm_id, self.SEEDS, stub=self.stub(algorithm_id))

    def test_mistake_fails_and_is_named(self, algorithm_id, name):
        allowed = getattr(self, "MISTAKES_MAY_CALL", self.IDS)
        assert_mistake_fails_and_is_named(algorithm_id, name, self.SEEDS, allowed=allowed)


class ChapterChecks(MistakeBankChecks):
    """:class:`MistakeBankChecks` and the rest a chapter owes: the hidden cases are reproducible
    and depend on the seed, the reference passes everywhere (and is named no mistake), every id
    has a correct alternative and every alternative passes everywhere.

    ``ALTERNATIVES`` maps each id to one correct alternative (a chapter's file passes only its
    own ids); ``EXTRA_ALTERNATIVES`` lists further ``(id, function)`` pairs.
    """

    ALTERNATIVES: dict = {}
    EXTRA_ALTERNATIVES: tuple = ()
    #: whether the NaNs of two fingerprints compare equal
    EQUAL_NAN = False

    _PARAMETERS = {
        **MistakeBankChecks._PARAMETERS,
        "test_hidden_cases_are_reproducible_and_depend_on_the_seed": "_ids",
        "test_reference_passes": "_ids",
        "test_correct_alternative_passes": "_alternatives",
    }

    def _alternatives(self):
        pairs = list(self.ALTERNATIVES.items()) + list(self.EXTRA_ALTERNATIVES)
        return ("algorithm_id", "function"), pairs, function_ids(pairs)

    # what a chapter may change: methods, so that a subclass overrides them in place
    def fingerprint(self, case):
        """What must be the same when a case is drawn twice from one seed."""
        return describe_and_array_args(case)

    def varies(self, case):
        """What must change with the seed (some case of another seed differs in it)."""
        return self.fingerprint(case)

    def reference_check(self, algorithm_id):
        """The check the reference is graded with (``None``: as registered)."""
        return None

    def test_hidden_cases_are_reproducible_and_depend_on_the_seed(self, algorithm_id):
        assert_hidden_cases_reproducible(check_of(algorithm_id), self.fingerprint, varies=self.varies,
                                         equal_nan=self.EQUAL_NAN)

    def test_reference_passes(self, algorithm_id):
        assert_reference_passes(algorithm_id, self.SEEDS, check=self.reference_check(algorithm_id))

    def test_correct_alternative_passes(self, algorithm_id, function):
        assert_passes_everywhere(algorithm_id, function, self.SEEDS)

    def test_every_algorithm_has_an_alternative(self):
        assert set(self.ALTERNATIVES) == set(self.IDS)


class WholeModuleChecks(ChapterChecks):
    """:class:`ChapterChecks` of a chapter that covers a whole module of the library (the one
    its ``IDS`` are in): its ``IDS`` and its ``MEASURED`` exercises (graded by what they reach,
    tested on their own) are exactly the algorithms registered in that module."""

    MEASURED: tuple = ()

    def test_every_algorithm_of_the_module_has_a_check(self):
        modules = {algorithm_id.split(".")[0] for algorithm_id in self.IDS}
        assert len(modules) == 1, f"the ids of {type(self).__name__} are in several modules: {sorted(modules)}"
        assert_ids_are_the_module(list(self.IDS) + list(self.MEASURED), modules.pop())
