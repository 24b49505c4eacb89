"""A course folder moved or copied elsewhere grades into its own gradebook.

cvkit gives a course folder outside the project (``--course-dir``, ``cvkit demo --dir``) a small
``nbgrader_config.py`` that loads the project's configuration. It used to write the folder's
absolute path into that file, so after ``mv course2026 archive/`` or ``cp -r course2026
course2027`` nbgrader — the writer of every grade — kept working on the old folder: the grades
went into the old gradebook (or nowhere), and the run ended with "no grade recorded" for every
submission. The file now roots the course at its own folder, and one written by an earlier
cvkit is brought up to date when the course is opened, changing only that line. Likewise after
the checkout moved: the file is pointed at the project in use, not left loading nothing."""
import os
import shutil
import sqlite3

from nbgrader.api import Gradebook
from traitlets.config.loader import PyFileConfigLoader

from cvkit.course import Course
from cvkit.course.state import CourseState

from course_helpers import SETUP, TEMPORAL_MEAN, exercise_cells, new_cell, new_notebook, submitted, write_project
from course_helpers import TEMPORAL_MEAN_LOOP as LOOP

ASSIGNMENT = "ch96_moved"
PLAN = f'[course]\nid = "moved-course"\n\n[[assignment]]\nid = "{ASSIGNMENT}"\n'
OLD_STYLE_ROOT = "_os.environ['CVKIT_COURSE_ROOT'] = {!r}\n"


def _project(tmp_path):
    notebook = new_notebook([new_cell(SETUP, "setup"),
                             *exercise_cells("filters.temporal_mean", "temporal_mean", TEMPORAL_MEAN)], ids=True)
    return write_project(tmp_path / "project", PLAN, {f"{ASSIGNMENT}/{ASSIGNMENT}.ipynb": notebook}), notebook


def _root_nbgrader_sees(folder):
    """The course root nbgrader takes from ``folder``'s configuration, loaded as nbgrader loads it
    (in nbgrader's process: what the configuration sets in the environment, such as
    ``CVKIT_TRUSTED_GRADING``, is taken back here, or every later test's checks would be no-ops)."""
    saved = dict(os.environ)
    try:
        config = PyFileConfigLoader("nbgrader_config.py", path=str(folder)).load_config()
    finally:
        os.environ.clear()
        os.environ.update(saved)
    return config.CourseDirectory.root


def test_the_generated_configuration_names_no_folder_and_follows_a_move(tmp_path):
    project, _ = _project(tmp_path)
    CourseState(tmp_path / "a", project=project)
    text = (tmp_path / "a" / "nbgrader_config.py").read_text()
    assert str(tmp_path / "a") not in text
    shutil.move(tmp_path / "a", tmp_path / "b")
    assert _root_nbgrader_sees(tmp_path / "b") == str(tmp_path / "b")


def test_an_earlier_generated_configuration_is_rooted_again_and_keeps_the_instructors_lines(tmp_path):
    project, _ = _project(tmp_path)
    CourseState(tmp_path / "old", project=project)
    config = tmp_path / "old" / "nbgrader_config.py"
    current = config.read_text()
    root_line = next(line for line in current.splitlines(keepends=True) if "CVKIT_COURSE_ROOT'] =" in line)
    earlier = current.replace(root_line, OLD_STYLE_ROOT.format(str(tmp_path / "old"))) + "c.Exchange.timezone = 'UTC'\n"
    config.write_text(earlier)
    shutil.copytree(tmp_path / "old", tmp_path / "copy")
    assert _root_nbgrader_sees(tmp_path / "copy") == str(tmp_path / "old")  # the trap, before it is opened

    CourseState(tmp_path / "copy", project=project)
    upgraded = (tmp_path / "copy" / "nbgrader_config.py").read_text()
    assert upgraded == current + "c.Exchange.timezone = 'UTC'\n"
    assert _root_nbgrader_sees(tmp_path / "copy") == str(tmp_path / "copy")


def test_after_the_checkout_moved_the_configuration_loads_the_project_in_use(tmp_path):
    project, _ = _project(tmp_path)
    CourseState(tmp_path / "course", project=project)
    shutil.move(project, tmp_path / "checkout2")
    assert _root_nbgrader_sees(tmp_path / "course") != str(tmp_path / "course")  # nbgrader's defaults: the trap

    state = CourseState(tmp_path / "course", project=tmp_path / "checkout2")
    text = (tmp_path / "course" / "nbgrader_config.py").read_text()
    assert str(tmp_path / "checkout2" / "autograders" / "nbgrader_config.py") in text and str(project) + "/" not in text
    assert _root_nbgrader_sees(tmp_path / "course") == str(tmp_path / "course")
    assert state.project == tmp_path / "checkout2"


def test_a_configuration_the_instructor_wrote_is_not_touched(tmp_path):
    project, _ = _project(tmp_path)
    (tmp_path / "mine").mkdir()
    mine = f"c = get_config()  # noqa\nc.CourseDirectory.root = {str(tmp_path / 'elsewhere')!r}\n"
    (tmp_path / "mine" / "nbgrader_config.py").write_text(mine)
    CourseState(tmp_path / "mine", project=project)
    assert (tmp_path / "mine" / "nbgrader_config.py").read_text() == mine


def test_a_copied_course_records_its_grades_in_its_own_gradebook(tmp_path):
    project, notebook = _project(tmp_path)
    first = Course(tmp_path / "course2026", project=project)
    first.build([ASSIGNMENT])
    first.submit("ada", ASSIGNMENT, {f"{ASSIGNMENT}.ipynb": submitted(notebook, {"temporal_mean_answer": LOOP})})
    shutil.copytree(tmp_path / "course2026", tmp_path / "course2027")
    shutil.rmtree(tmp_path / "course2026")  # moved: nothing left where it was

    results = Course(tmp_path / "course2027", project=project).grade([ASSIGNMENT], workers=1)

    assert [(r.student, r.ok) for r in results] == [("ada", True)], [r.log[-300:] for r in results]
    with Gradebook(f"sqlite:///{tmp_path / 'course2027' / 'gradebook.db'}") as gradebook:
        assert gradebook.find_submission(ASSIGNMENT, "ada").score == 3
    assert not (tmp_path / "course2026").exists()
    with sqlite3.connect(tmp_path / "course2027" / "gradebook.db") as db:  # a clash would name the new folder
        assert list(db.execute("SELECT course_id, folder FROM cvkit_course")) == [("moved-course", str(tmp_path / "course2027"))]
