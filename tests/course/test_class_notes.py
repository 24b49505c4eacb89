"""Class-wide notes next to a named mistake on the feedback pages (plan.toml [class_notes], off
by default): aggregate shares only, above a minimum class size, idempotent, removable."""
from __future__ import annotations

import re

import numpy as np
import pytest

from cvkit.course.class_notes import (DEFAULT_MIN_CLASS, MIN_CLASS_FLOOR, Settings, annotate, mistake_shares, note,
                                      settings)
from cvkit.grading import evaluate
from cvkit.course.safety import sanitize_html

ONES = "not normalised (all ones)"


@pytest.fixture(scope="module")
def page():
    """A page with two trusted reports as the feedback pages hold them (sanitized): the mean kernel's
    with a named mistake, and a passing one."""
    wrong = evaluate("filters.mean_kernel", lambda size: np.ones((size, size)), hidden=True, seed=5)
    right = evaluate("filters.mean_kernel", lambda size: np.full((size, size), 1.0 / size ** 2))
    assert wrong.mistake == ONES and right.passed
    body = "".join(sanitize_html(r._repr_html_(), trusted_report=True) for r in (wrong, right))
    return f"<html><body><p>answer</p>{body}</body></html>"


def test_settings_are_off_by_default_and_checked():
    assert settings({}) == Settings(False, DEFAULT_MIN_CLASS)
    assert settings({"class_notes": {"enabled": True}}) == Settings(True, DEFAULT_MIN_CLASS)
    assert settings({"class_notes": {"enabled": True, "min_class": 12}}) == Settings(True, 12)
    for bad, words in (({"enabled": "yes"}, "true or false"), ({"min_class": MIN_CLASS_FLOOR - 1}, "at least"),
                       ({"min_class": 12.5}, "whole number"), ({"enable": True}, "unknown key")):
        with pytest.raises(ValueError, match=words):
            settings({"class_notes": bad})
    with pytest.raises(ValueError, match="must be a table"):
        settings({"class_notes": True})


def test_shares_need_the_minimum_class_and_another_student():
    named = {f"s{i}": [("filters.mean_kernel", ONES)] if i < 9 else [] for i in range(22)}
    named["s21"] = [("filters.pad", "wrong border")]  # one student only: never "too"
    assert mistake_shares(named, 20) == {("filters.mean_kernel", ONES): (9, 22)}
    assert mistake_shares(named, 23) == {}
    assert mistake_shares({}, 20) == {}
    # a student counted once, whether the visible or the hidden report named it
    assert mistake_shares({"a": [("x", "m"), ("x", "m")], "b": [("x", "m")]}, 2) == {("x", "m"): (2, 2)}


def test_note_is_a_rounded_share_in_plain_words():
    assert note(9, 22) == "40 % of the class made this mistake too."
    assert note(22, 22) == "100 % of the class made this mistake too."
    assert note(299, 300) == "99 % of the class made this mistake too."
    assert note(2, 400) == "A few others in the class made this mistake too."


def test_annotate_adds_one_note_after_the_named_mistake_only(page):
    shares = {("filters.mean_kernel", ONES): (9, 22)}
    done = annotate(page, shares)
    notes = re.findall(r"<p class=\"cvkit-class-note\">([^<]*)</p>", done)
    assert notes == ["40 % of the class made this mistake too."]
    assert done.index("cvkit-class-note") > done.index("cvkit-mistake")
    assert done.replace('<p class="cvkit-class-note">40 % of the class made this mistake too.</p>', "") == page
    assert annotate(done, shares) == done                       # idempotent
    assert annotate(done, {}) == page                           # switched off: removed
    assert annotate(page, {("filters.pad", ONES): (9, 22)}) == page  # another exercise's mistake: no note


def test_annotate_leaves_a_page_without_reports_alone():
    text = "<p class=\"cvkit-mistake\">Your output matches a known mistake: <b>x</b>.</p>"  # not in a report
    assert annotate(text, {("a", "x"): (3, 20)}) == text


def test_the_plan_reader_accepts_the_table(tmp_path):
    from cvkit.course.class_notes import read_settings
    from cvkit.course.plan import read_plan

    plan = tmp_path / "plan.toml"
    plan.write_text('[[assignment]]\nid = "ch03_filtering"\n\n[class_notes]\nenabled = true\nmin_class = 15\n')
    assert read_plan(plan).ids() == ["ch03_filtering"]
    assert read_settings(plan) == Settings(True, 15)
    assert read_settings(tmp_path / "none.toml") == Settings()
    plan.write_text("[class_notes\n")
    with pytest.raises(ValueError, match="not valid TOML"):
        read_settings(plan)
