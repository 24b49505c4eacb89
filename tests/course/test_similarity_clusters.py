"""cvkit.course.similarity at class scale: groups of similar answers, not pairs (issue #37, item 5).

Test data: a simulated class (``tests/course/simulated_class.py``): every student answers Chapter 3's
13 exercises with a variation (names changed, independent statements swapped, comments added)
of one of three sources — the instructor's solution, cvkit's reference, the independent
version of ``tests/library/alternatives_ch03.py`` — and a few students answer on their own. The answers
are given to the similarity module directly (no grading)."""
from __future__ import annotations

import csv
import inspect
import random
from collections import Counter
from itertools import combinations

import pytest

from cvkit.course import similarity
from cvkit.course.similarity import SOLUTION, THRESHOLD, SimilarGroup, SimilarPair, reference_label

pytest.importorskip("copydetect")
import alternatives_ch03  # noqa: E402
import simulated_class  # noqa: E402

MB = 2**20


@pytest.fixture(scope="module")
def chapter():
    """(exercises, the three sources of every exercise)."""
    exercises = simulated_class.exercises()
    sources = simulated_class.sources(exercises)
    assert len(sources) == 13
    return {grade_id: exercises[grade_id] for grade_id in sources}, sources


def _class(chapter, students: int, seed: int):
    exercises, sources = chapter
    answers = simulated_class.answers(students, unique=3, seed=seed, chosen=sources)
    pairs = similarity.similar_pairs(answers, exercises, assignment="ch03_filtering")
    return answers, pairs, similarity.groups(pairs)


@pytest.fixture(scope="module")
def class_of_60(chapter):
    return _class(chapter, 60, seed=1)


def _expected_textbook(kind: str, exercise) -> tuple[str, ...]:
    return {"solution": (SOLUTION,), "reference": (reference_label(exercise.reference_name),),
            "alternative": ()}[kind]


# ------------------------------------------------------------------------------- class scale
def test_a_class_of_60_from_three_sources_gives_one_group_per_source_and_a_page_under_2_mb(chapter, class_of_60,
                                                                                          tmp_path):
    exercises, _ = chapter
    answers, pairs, groups = class_of_60
    # what a list of pairs would show: thousands (each source's 19 students, pairwise, per exercise)
    assert len(pairs) > 13 * 3 * 171
    assert len(groups) == 13 * 3
    for grade_id, exercise in exercises.items():
        found = [g for g in groups if g.exercise == grade_id]
        by_source = {}
        for group in found:
            kinds = {simulated_class.source_of(m.name) for m in group.members}
            assert len(kinds) == 1, (grade_id, kinds)  # no group mixes two sources
            by_source[kinds.pop()] = group
        assert set(by_source) == set(simulated_class.SOURCES)
        for kind, group in by_source.items():
            assert {m.name for m in group.members} == {s for s in answers if simulated_class.source_of(s) == kind}
            # the textbook groups are labelled as such; the common source that is no textbook is not
            assert tuple(m.name for m in group.textbook) == _expected_textbook(kind, exercise), (grade_id, kind)
            assert all(m.similarity >= THRESHOLD for m in group.members + group.textbook)
    # the students who answered on their own are in no group
    assert not any(m.name.startswith("u") for g in groups for m in g.members)
    # groups of students first, textbook groups after
    assert [bool(g.textbook) for g in groups] == sorted(bool(g.textbook) for g in groups)

    page = similarity.write_html(groups, tmp_path / "similarity.html")
    text = page.read_text(encoding="utf-8")
    assert page.stat().st_size < 2 * MB, page.stat().st_size
    # one side-by-side view per group: its central answer and its answer least like it, and in the
    # 26 textbook groups the textbook text too
    assert text.count("<section") == 39 and text.count('class="sides"') == 39
    assert text.count("<pre>") == 13 * 2 + 26 * 3
    assert text.count('class="note">Textbook answer') == 26
    rows = list(csv.DictReader(similarity.write_csv(groups, tmp_path / "similarity.csv").open(encoding="utf-8")))
    assert len(rows) == 13 * 57  # one row per student of a group
    assert Counter(row["cluster"] for row in rows) == Counter({str(n): 19 for n in range(1, 40)})
    assert {row["textbook"] for row in rows} == {"", SOLUTION} | {
        reference_label(e.reference_name) for e in exercises.values()}


def test_a_class_of_300_stays_a_few_mb_and_grows_with_the_class_not_its_square(chapter, class_of_60, tmp_path):
    _, pairs, groups = _class(chapter, 300, seed=2)
    assert len(pairs) > 13 * 3 * 4851  # 99 students per source
    assert len(groups) == 39 and sum(len(g.members) for g in groups) == 13 * 297
    big = similarity.write_html(groups, tmp_path / "300.html").stat().st_size
    small = similarity.write_html(class_of_60[2], tmp_path / "60.html").stat().st_size
    assert big < 3 * MB, big
    # five times the students (4.9 times the pairs' square root): the page grows about five times
    assert big < 6 * small, (big, small)


def test_a_copied_pair_among_unique_answers_is_a_group_of_two(chapter, tmp_path):
    exercises, sources = chapter
    grade_id = "bilateral_answer"
    unique = simulated_class.unique_answers(grade_id)
    answers = {f"own{n:02d}": {grade_id: text} for n, text in enumerate(unique)}
    assert similarity.similar_pairs(answers, exercises) == []  # answers of their own: nothing alike
    original = sources[grade_id]["alternative"]
    answers["cop_a"] = {grade_id: simulated_class.vary(original, random.Random(5))}
    answers["cop_b"] = {grade_id: simulated_class.vary(original, random.Random(6))}
    assert answers["cop_a"] != answers["cop_b"]
    groups = similarity.groups(similarity.similar_pairs(answers, exercises, assignment="ch03"))
    assert len(groups) == 1
    group = groups[0]
    assert [m.name for m in group.members] == ["cop_a", "cop_b"] and group.textbook == ()
    assert group.members[0].closest == "cop_b" and group.members[1].closest == "cop_a"
    assert group.members[0].similarity >= THRESHOLD
    # the two answers side by side
    assert [m.source for m in group.shown()] == [answers["cop_a"][grade_id], answers["cop_b"][grade_id]]
    rows = list(csv.reader(similarity.write_csv(groups, tmp_path / "s.csv").open(encoding="utf-8")))
    assert [row[2:6] for row in rows[1:]] == [["1", "2", "cop_a", "cop_b"], ["1", "2", "cop_b", "cop_a"]]


def test_the_textbook_group_is_labelled_and_shown_beside_the_textbook(chapter, tmp_path):
    exercises, sources = chapter
    grade_id = "gaussian_answer"
    answers = {f"st{n}": {grade_id: simulated_class.vary(sources[grade_id]["solution"], random.Random(n))}
               for n in range(4)}
    answers["pair_a"] = {grade_id: simulated_class.vary(sources[grade_id]["alternative"], random.Random(10))}
    answers["pair_b"] = {grade_id: simulated_class.vary(sources[grade_id]["alternative"], random.Random(11))}
    groups = similarity.groups(similarity.similar_pairs(answers, exercises))
    assert [sorted(m.name for m in g.members) for g in groups] == [["pair_a", "pair_b"], ["st0", "st1", "st2", "st3"]]
    textbook = groups[1]
    assert [m.name for m in textbook.textbook] == [SOLUTION] and groups[0].textbook == ()
    shown = textbook.shown()  # a small group: every answer, then the textbook text
    assert [m.name for m in shown[:-1]] == [m.name for m in textbook.members] and shown[0] == textbook.centre
    assert shown[-1].name == SOLUTION and shown[-1].source == exercises[grade_id].solution
    page = similarity.write_html(groups, tmp_path / "s.html").read_text(encoding="utf-8")
    second = page[page.index('id="cluster-2"'):]
    assert "Textbook answer: this group is close to (instructor&#x27;s solution)" in second
    assert "<tr><td>(instructor&#x27;s solution) (textbook)</td>" in second  # listed with its closest student
    assert "Textbook answer" not in page[page.index('id="cluster-1"'):page.index('id="cluster-2"')]
    rows = list(csv.DictReader(similarity.write_csv(groups, tmp_path / "s.csv").open(encoding="utf-8")))
    assert {row["student"]: row["textbook"] for row in rows} == {
        "pair_a": "", "pair_b": "", **{f"st{n}": SOLUTION for n in range(4)}}


def test_a_pasted_reference_alone_is_a_group_of_one_student_and_the_reference(chapter):
    exercises, sources = chapter
    answers = {"cat": {"median_answer": simulated_class.vary(sources["median_answer"]["reference"], random.Random(3))},
               "dan": {"median_answer": sources["median_answer"]["alternative"]}}
    groups = similarity.groups(similarity.similar_pairs(answers, exercises))
    assert len(groups) == 1 and [m.name for m in groups[0].members] == ["cat"]
    assert [m.name for m in groups[0].textbook] == [reference_label("cvkit.filters.median")]
    assert groups[0].members[0].closest == reference_label("cvkit.filters.median")


# ------------------------------------------------------------------------------- grouping
def test_every_reported_pair_is_inside_one_group(class_of_60):
    _, pairs, groups = class_of_60
    where = {}
    for number, group in enumerate(groups):
        for member in group.members + group.textbook:
            where.setdefault((group.exercise, member.name), set()).add(number)
    for pair in pairs:
        first, second = where[(pair.exercise, pair.a)], where[(pair.exercise, pair.b)]
        assert first & second, pair  # no pair is hidden between two groups
    students = [(g.exercise, m.name) for g in groups for m in g.members]
    assert len(students) == len(set(students))  # and a student is in one group per exercise


def test_a_chain_is_one_group_whose_members_say_how_they_are_linked():
    def pair(a, b, value):
        return SimilarPair("ex", a, b, value, f"text of {a}", f"text of {b}", "hw1")

    pairs = [pair("ann", "bob", 0.9), pair("bob", "cyd", 0.7), pair("cyd", "dan", 0.65), pair("dan", "eli", 0.62),
             pair("eve", "fay", 0.8), pair("gus", "hal", 0.99)]
    groups = similarity.groups(pairs + [SimilarPair("other", "ann", "bob", 0.61, "x", "y", "hw1")])
    assert [[m.name for m in g.members] for g in groups] == [
        ["gus", "hal"], ["bob", "ann", "cyd", "dan", "eli"], ["eve", "fay"], ["ann", "bob"]]
    chain = groups[1]
    assert chain.centre.name == "bob" and chain.centre.to_centre == 1.0  # 0.9 + 0.7: the most linked
    members = {m.name: m for m in chain.members}
    assert (members["ann"].closest, members["ann"].similarity, members["ann"].to_centre) == ("bob", 0.9, 0.9)
    assert (members["dan"].closest, members["dan"].similarity, members["dan"].to_centre) == ("cyd", 0.65, None)
    assert (chain.low, chain.high) == (0.62, 0.9)
    # more than SHOWN_ALL students: the central answer beside the first of those least like it
    assert [m.name for m in chain.shown()] == ["bob", "dan"] and len(chain.members) > similarity.SHOWN_ALL
    assert [m.name for m in groups[2].shown()] == ["eve", "fay"]
    assert similarity.groups([]) == []
    with pytest.raises(TypeError, match="pairs must be an iterable of SimilarPair"):
        similarity.groups(["ann"])  # type: ignore[list-item]


def test_groups_and_pairs_are_written_alike(class_of_60, tmp_path):
    _, pairs, groups = class_of_60
    assert all(isinstance(g, SimilarGroup) for g in groups)
    from_pairs = similarity.write_csv(pairs, tmp_path / "p.csv").read_text(encoding="utf-8")
    assert from_pairs == similarity.write_csv(groups, tmp_path / "g.csv").read_text(encoding="utf-8")
    page = similarity.write_html(pairs, tmp_path / "p.html").read_text(encoding="utf-8")
    assert page == similarity.write_html(groups, tmp_path / "g.html").read_text(encoding="utf-8")


def test_hostile_names_and_texts_in_a_group_stay_escaped(tmp_path):
    hostile = "<script>alert(1)</script>"
    pairs = [SimilarPair("ex", hostile, "=cmd()", 0.9, "</pre><img src=x onerror=alert(2)>", "<b>b</b>", "hw"),
             SimilarPair("ex", hostile, "<i>c</i>", 0.8, "</pre><img src=x onerror=alert(2)>", "<u>x</u>", "hw"),
             SimilarPair("ex2", "<i>c</i>", SOLUTION, 0.7, "<b>b</b>", "</pre><script>", "hw", textbook=True)]
    page = similarity.write_html(pairs, tmp_path / "s.html").read_text(encoding="utf-8")
    assert "<script" not in page.lower() and "<img" not in page.lower() and "<b>" not in page and "<i>" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt; (central)" in page and "&lt;/pre&gt;&lt;img" in page
    assert "&lt;u&gt;x&lt;/u&gt;" in page and "&lt;/pre&gt;&lt;script&gt;" in page  # every shown text escaped
    rows = list(csv.reader(similarity.write_csv(pairs, tmp_path / "s.csv").open(encoding="utf-8")))
    assert [row[4] for row in rows[1:]] == [hostile, "<i>c</i>", "'=cmd()", "<i>c</i>"]
    assert [row[7] for row in rows[1:]] == ["", "", "", SOLUTION]


# ------------------------------------------------------------------------------- the comparison
def test_the_vectorized_values_are_copydetects_on_the_simulated_class(chapter):
    """The report takes the vectorized value (copydetect's own is computed only near the
    threshold): on the simulated class's answers the two agree."""
    from copydetect import compare_files

    exercises, sources = chapter
    answers = simulated_class.answers(30, unique=3, seed=7, chosen=sources, distinct=True)
    checked = batched = 0
    for grade_id in ("add_salt_and_pepper_answer", "nl_means_answer", "pad_answer"):
        comparer = similarity._Comparer(exercises[grade_id].stub)
        texts = sorted({similarity._normalised(a[grade_id]) for a in answers.values()})
        for text in texts:
            comparer.size(text)
        documents = [comparer.documents[t] for t in texts]
        for one in documents:
            for two in documents[:12]:
                _, shares, _ = compare_files(one.fingerprint, two.fingerprint)
                assert (one.share(two), two.share(one)) == pytest.approx(shares, abs=1e-12)
                checked += 1
        # all the pairs at once (what similar_pairs uses) give the same values as one pair at a time
        comparer.measure_all(texts)
        for one, two in combinations(texts, 2):
            key = (one, two) if one <= two else (two, one)
            first, second = comparer.documents[one], comparer.documents[two]
            assert comparer.values[key] == pytest.approx((first.share(second) + second.share(first)) / 2, abs=1e-12)
            batched += 1
    assert checked > 300 and batched > 300
