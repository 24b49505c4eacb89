"""A submission's way to the gradebook, counted: how often cvkit parses it, how often nbgrader runs.

A marker in the student's answer makes every text of this submission recognisable. Every JSON
or nbformat read of such a text made by cvkit's own code (the caller's module is in ``cvkit``)
is counted while the worker grades the submission and the writer records it, in this process:

- the worker parses the submitted notebook once (``cvkit.course.notebook.Submitted.parse``) and
  the executed notebook once when it comes back from the sandbox (``cvkit.course.jobs``); the
  run inside the sandbox (another process) reads its own copy once;
- the writer parses nothing: the verdicts travel as the notebook's text and the flags beside it;
  nbgrader reads the staged file (its own reads are not cvkit's);
- nbgrader's ``autograde`` runs once for the submission.
"""
from __future__ import annotations

import json
import sys

import nbformat
import pytest

from cvkit.course import Course, jobs
from cvkit.course.writer import Writer

MARKER = "parse-count-marker-5b1e"
CHAPTER = "ch02_image_formation"


@pytest.fixture(scope="module")
def course(tmp_path_factory):
    made = Course(tmp_path_factory.mktemp("parse-count") / "course")
    (made.root / ".grading_salt").write_text("parse-count")
    made.build([CHAPTER])
    release = made.release_notebooks(CHAPTER)[0]
    nb = json.loads(release.read_text())
    answers = [cell for cell in nb["cells"] if cell.get("metadata", {}).get("nbgrader", {}).get("solution")
               and cell["cell_type"] == "code"]
    answers[0]["source"] = f"# {MARKER}\n" + "".join(answers[0]["source"])
    made.submit("ada", CHAPTER, {release.name: nb})
    return made


def _counting(monkeypatch, counts: dict[str, list[str]]) -> None:
    """Count each read, by cvkit's code, of a text that holds the marker."""
    def wrap(module, name, of_text):
        original = getattr(module, name)

        def counted(*args, **kwargs):
            caller = sys._getframe(1).f_globals.get("__name__", "")
            if caller.startswith("cvkit") and MARKER in of_text(args[0]):
                counts.setdefault(f"{module.__name__}.{name}", []).append(caller)
            return original(*args, **kwargs)

        monkeypatch.setattr(module, name, counted)

    def text(value):
        return value.decode("utf-8", "replace") if isinstance(value, bytes) else str(value)

    wrap(json, "loads", text)
    wrap(nbformat, "reads", text)
    wrap(nbformat, "read", lambda f: MARKER)  # by path or file: any read by cvkit counts


def test_cvkit_parses_a_submission_twice_and_nbgrader_runs_once(course, monkeypatch):
    import nbgrader.apps.api as nbgrader_api

    counts: dict[str, list[str]] = {}
    runs: list[str] = []
    original = nbgrader_api.NbGraderAPI.autograde

    def autograde(self, assignment_id, student_id, *args, **kwargs):
        runs.append(student_id)
        return original(self, assignment_id, student_id, *args, **kwargs)

    monkeypatch.setattr(nbgrader_api.NbGraderAPI, "autograde", autograde)
    job = jobs.payload(course, "ada", CHAPTER)
    _counting(monkeypatch, counts)
    executed = jobs.grade_submission(*job)
    in_worker = {key: list(callers) for key, callers in counts.items()}
    counts.clear()
    results = Writer(course).record_many([executed])
    in_writer = {key: list(callers) for key, callers in counts.items()}

    assert executed.verified and results[0].ok, results[0].log
    parses = [caller for callers in in_worker.values() for caller in callers]
    assert sorted(parses) == ["cvkit.course.jobs", "cvkit.course.notebook"], in_worker
    assert in_writer == {}, in_writer
    assert runs == ["ada"]
    graded = course.root / "autograded" / "ada" / CHAPTER
    assert MARKER in next(graded.glob("*.ipynb")).read_text()  # the submission did reach nbgrader


def test_a_grading_run_reads_each_submission_folder_once(course, monkeypatch):
    """``cvkit course grade`` reads a submission's folder once: the job's files, the journal's hash,
    the received time, the staged copy and the refused files' flags are one version of it."""
    from cvkit.course import journal, received, state

    release = course.release_notebooks(CHAPTER)[0]
    course.submit("bob", CHAPTER, {release.name: json.loads(release.read_text())})
    reads: dict[str, int] = {}
    for module in (state, journal, received):
        original = module.collect_files

        def counted(folder, *args, _original=original, **kwargs):
            reads[str(folder)] = reads.get(str(folder), 0) + 1
            return _original(folder, *args, **kwargs)

        monkeypatch.setattr(module, "collect_files", counted)
    results = course.grade([CHAPTER], workers=1, regrade=True)
    assert all(r.ok for r in results), [r.log for r in results]
    folders = {str(course.root / "submitted" / s / CHAPTER) for s in ("ada", "bob")}
    assert {f: reads.get(f, 0) for f in folders} == {f: 1 for f in folders}, reads
