"""An instructor's own exercises in a course package (issue #20): the scaffold, every command of
the how-to docs/own-exercise.md, and the example package examples/cvkit-course-example/
installed with pip and graded through the real course pipeline (nbgrader, the sandbox)."""
import contextlib
import io
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from cvkit import registry, scaffold
from cvkit.cli import main
from cvkit.grading import evaluate

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "cvkit-course-example"
HOWTO = ROOT / "docs" / "own-exercise.md"
ID = "mycourse.gamma_correction"
CHAPTER = "ch02_image_formation"
IGNORED = shutil.ignore_patterns("build", "*.egg-info", "__pycache__")


# ------------------------------------------------------------------ the how-to, read as data
def _blocks(kind: str) -> list[str]:
    found = re.findall(rf"^ *```{kind}\n(.*?)^ *```", HOWTO.read_text(encoding="utf-8"), re.S | re.M)
    return [textwrap.dedent(block) for block in found]


def _commands() -> dict[str, list[str]]:
    """``{command: the output lines the how-to shows}`` of its console blocks."""
    commands: dict[str, list[str]] = {}
    current = None
    for block in _blocks("console"):
        for line in block.splitlines():
            if line.startswith("$ "):
                current = commands.setdefault(line[2:], [])
            elif current is not None:
                current.append(line)
    return commands


def _argv(command: str) -> list[str]:
    words = shlex.split(command)
    assert words[0] == "cvkit", command
    return words[1:]


SCAFFOLD = "cvkit new exercise mycourse.gamma_correction --package mycourse-course --section 2.12"
INSTALL = "pip install -e mycourse-course"
VALIDATE = "cvkit list mycourse --validate"
BUILD = f"cvkit course build --assignment {CHAPTER}"
GRADE = f"cvkit course grade --assignment {CHAPTER}"


def test_every_command_of_the_how_to_is_run_here():
    """The tests below run exactly these commands (pip with --target instead of the venv)."""
    assert list(_commands()) == [SCAFFOLD, INSTALL, VALIDATE, BUILD, GRADE]


def _pip(*args: str) -> None:
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", *args],
                          capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        pytest.fail(f"pip install {' '.join(args)} failed:\n{done.stderr[-2000:]}")


# ------------------------------------------------------------------ scaffold
def _run(argv, capsys) -> tuple[int, str, str]:
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err


def test_scaffold_writes_the_files_the_how_to_shows(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    status, out, _ = _run(_argv(SCAFFOLD), capsys)
    assert status == 0 and out.splitlines() == _commands()[SCAFFOLD]
    package = tmp_path / "mycourse-course"
    assert sorted(str(p.relative_to(package)) for p in package.rglob("*") if p.is_file()) == [
        "gamma_correction_cells.ipynb", "mycourse/__init__.py", "mycourse/gamma_correction.py", "pyproject.toml"]
    import tomllib

    project = tomllib.loads((package / "pyproject.toml").read_text())
    assert project["project"]["entry-points"]["cvkit.algorithms"] == {"mycourse": "mycourse"}
    module = (package / "mycourse" / "gamma_correction.py").read_text()
    compile(module, "gamma_correction.py", "exec")
    assert '@cvkit.algorithm("mycourse.gamma_correction", section="2.12", check=CHECK)' in module
    assert "@mistake(" in module and "mistakes=[_todo_mistake]" in module and "def _hidden(rng" in module and "def _public()" in module
    # the example package is what the scaffold writes, filled in
    for name in ("pyproject.toml", "mycourse/__init__.py"):
        assert (package / name).read_text() == (EXAMPLE / name).read_text(), name


def _chapter_with(cells_path: Path, folder: Path) -> Path:
    """A chapter notebook: the set-up cell of lectures/ch02, then the exercise's cells."""
    source = json.loads((ROOT / "lectures" / CHAPTER / f"{CHAPTER}.ipynb").read_text())
    setup = next(c for c in source["cells"] if c["cell_type"] == "code")
    fragment = json.loads(cells_path.read_text())
    nb = dict(fragment, cells=[{"cell_type": "markdown", "id": "title", "metadata": {}, "source": "# Chapter 2"},
                               setup] + fragment["cells"])
    path = folder / "chapter" / "chapter.ipynb"
    path.parent.mkdir(parents=True)
    path.write_text(json.dumps(nb))
    return path


@pytest.mark.parametrize("cells", ["scaffold", "example"])
def test_the_cells_follow_the_rules_of_the_lecture_notebooks(cells, tmp_path):
    import nbformat

    import test_notebooks

    if cells == "scaffold":
        path = tmp_path / "cells.ipynb"
        path.write_text(json.dumps(scaffold.exercise_cells(ID, "gamma_correction")))
    else:
        path = EXAMPLE / "gamma_correction_cells.ipynb"
    nbformat.validate(nbformat.read(path, as_version=4))
    chapter = _chapter_with(path, tmp_path)
    test_notebooks.test_exercise_structure(chapter)
    test_notebooks.test_solutions_are_written_from_scratch(chapter)
    test_notebooks.test_committed_without_outputs(chapter)
    kinds = [(c["cell_type"], c["metadata"].get("nbgrader", {}).get("grade_id"), c["metadata"].get("tags"))
             for c in json.loads(path.read_text())["cells"]]
    assert kinds == [("markdown", None, None), ("code", "gamma_correction_answer", None),
                     ("code", "gamma_correction_visible", ["raises-exception"]),
                     ("code", "gamma_correction_hidden", None)]


def test_scaffold_never_overwrites(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert _run(_argv(SCAFFOLD), capsys)[0] == 0
    module = tmp_path / "mycourse-course" / "mycourse" / "gamma_correction.py"
    module.write_text("# my own work\n")
    status, out, err = _run(_argv(SCAFFOLD), capsys)
    assert status == 2 and out == "" and "not overwriting mycourse-course/mycourse/gamma_correction.py" in err
    assert module.read_text() == "# my own work\n"
    # a second exercise of the same package adds its module and cells, nothing else
    status, out, _ = _run(["new", "exercise", "mycourse.box_blur", "--package", "mycourse-course"], capsys)
    assert status == 0
    assert [line for line in out.splitlines() if line.startswith("wrote")] == [
        "wrote mycourse-course/box_blur_cells.ipynb", "wrote mycourse-course/mycourse/box_blur.py"]


@pytest.mark.parametrize("algorithm_id, message", [
    ("filters.gamma", "belongs to a cvkit module"),
    ("gamma", "must look like '<course>.<name>'"),
    ("mycourse.class", "must be a public Python identifier"),
    ("MyCourse.gamma", "lower case letters"),
])
def test_scaffold_refuses_bad_ids(algorithm_id, message, tmp_path):
    with pytest.raises(ValueError, match=message) as info:
        scaffold.new_exercise(algorithm_id, tmp_path / "pkg")
    assert "algorithm_id" in str(info.value)
    assert not (tmp_path / "pkg").exists()


def test_scaffold_needs_the_entry_point_in_an_existing_pyproject(tmp_path):
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "mine"\n')
    with pytest.raises(ValueError, match=r"declares no entry point 'mycourse' in the group cvkit.algorithms"):
        scaffold.new_exercise(ID, tmp_path)
    with pytest.raises(ValueError, match="section"):
        scaffold.new_exercise("other.gamma", tmp_path / "other", section="")


# ------------------------------------------------------------------ the how-to, steps 1 to 3
def test_how_to_scaffold_editable_install_and_validate(tmp_path, monkeypatch):
    """Steps 1-3 as written: the stub is refused, the written module validates, and an editable
    install takes the edit without reinstalling."""
    site = tmp_path / "site"
    monkeypatch.chdir(tmp_path)
    assert main(_argv(SCAFFOLD)) == 0
    assert INSTALL.split()[:3] == ["pip", "install", "-e"]
    _pip("--target", str(site), "-e", str(tmp_path / INSTALL.split()[-1]))

    def validate():
        program = (f"import site, sys; site.addsitedir({str(site)!r}); from cvkit.cli import main; "
                   f"sys.exit(main({_argv(VALIDATE)!r}))")
        return subprocess.run([sys.executable, "-c", program], cwd=tmp_path, capture_output=True, text=True,
                              timeout=300)

    stub = validate()
    assert stub.returncode == 1, stub.stdout + stub.stderr
    assert ("course package 'mycourse-exercises' (entry point mycourse = mycourse): the check of "
            "'mycourse.gamma_correction' is refused: public case 1 (2x2 ramp): the reference raised "
            "NotImplementedError") in stub.stdout
    module = _blocks("python")[0]
    (tmp_path / "mycourse-course" / "mycourse" / "gamma_correction.py").write_text(module)  # step 2
    written = validate()
    assert written.returncode == 0, written.stdout + written.stderr
    assert written.stdout.splitlines() == _commands()[VALIDATE]


def test_how_to_module_is_the_example_package():
    assert _blocks("python")[0] == (EXAMPLE / "mycourse" / "gamma_correction.py").read_text()


# ------------------------------------------------------------------ the example, installed
@pytest.fixture(scope="module")
def example_site(tmp_path_factory):
    """The example package, installed with pip (not editable) into a folder of its own, so that
    the shared virtual environment is left alone; removed at the end."""
    site = tmp_path_factory.mktemp("example-site")
    source = tmp_path_factory.mktemp("example-source") / EXAMPLE.name  # pip builds in the folder: a copy
    shutil.copytree(EXAMPLE, source, ignore=IGNORED)
    _pip("--target", str(site), str(source))
    yield site
    shutil.rmtree(site, ignore_errors=True)


@contextlib.contextmanager
def _installed(site: Path):
    """The package visible here and in the processes started meanwhile (PYTHONPATH)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(site))
        patch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")])))
        registry.reload_plugins()
        try:
            yield
        finally:
            patch.undo()
            registry.reload_plugins()


@pytest.fixture
def installed(example_site):
    with _installed(example_site):
        yield example_site


def _right(image, gamma, vmax=1.0):
    return vmax * (np.asarray(image, dtype=np.float64) / vmax) ** gamma


def test_found_through_its_entry_point(installed, capsys):
    record = registry.get(ID)
    assert record.package == "course package 'mycourse-exercises' (entry point mycourse = mycourse)"
    assert record.section == "2.12" and ID in [a.id for a in registry.algorithms()]
    assert "mycourse" not in registry.package_errors()
    assert registry.validate(ID) == 2
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^mycourse\.gamma_correction +2\.12 +mycourse-exercises +reference +2 public, 3 mistakes$",
                     out, re.M)
    assert out.splitlines()[-1].endswith("algorithms (1 course package)")


def test_the_check_tells_right_from_every_mistake(installed):
    check = registry.get(ID).check
    assert evaluate(ID, _right).passed
    for seed in (1, 2, 3):
        assert evaluate(ID, _right, hidden=True, seed=seed).score == 1.0
        for mistake in check.mistakes:
            report = evaluate(ID, mistake.function, hidden=True, seed=seed)
            assert not report.passed and report.mistake == mistake.name, (seed, mistake.name)


def test_calling_the_reference_is_caught_in_the_notebook_too(installed):
    from mycourse.gamma_correction import gamma_correction as reference

    def gamma_correction(image, gamma, vmax=1.0):
        return reference(image, gamma, vmax)

    report = evaluate(ID, gamma_correction)
    assert not report.passed
    assert all("reference implementation of 'mycourse.gamma_correction'" in case.message for case in report.cases)


def test_the_how_to_check_output(installed):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(AssertionError, match="1/gamma instead of gamma"):
        exec(_blocks("python")[1], {})
    shown = _blocks("text")[0].splitlines()
    got = out.getvalue().splitlines()
    assert got[:len(shown)] == shown


def test_the_how_to_not_answered_line(installed, capsys):
    def gamma_correction(image, gamma, vmax=1.0):
        raise NotImplementedError()

    from cvkit.grading import check

    with pytest.raises(AssertionError) as raised:
        check(ID, gamma_correction)
    # said once, as the cell's error (nothing printed besides)
    assert str(raised.value).strip() == _blocks("text")[1].strip()
    assert capsys.readouterr().out.strip() == ""


def test_answer_cells_cannot_reach_the_package(installed):
    """In the grading sandbox an answer cell may import NumPy, math and a little of the
    standard library: the course package is refused by name, and its files are not there."""
    from cvkit.sandbox.session import run_calls

    import mycourse.gamma_correction as reference_module  # importable on the trusted side

    path = reference_module.__file__
    result = run_calls([f"from {ID} import gamma_correction as reference\n",
                        f"source = open({path!r}).read()\n"], [])
    assert result.started and "import mycourse.gamma_correction (not allowed in graded code)" in result.refused
    assert any(e.startswith("cell 0: ImportError: mycourse.gamma_correction is not allowed") for e in result.cell_errors)
    assert any(e.startswith("cell 1: FileNotFoundError") for e in result.cell_errors), result.cell_errors


# ------------------------------------------------------------------ the how-to, steps 4 and 5
def _answer(release: dict, source: str | None) -> dict:
    nb = json.loads(json.dumps(release))
    for cell in nb["cells"]:
        if cell["metadata"].get("nbgrader", {}).get("grade_id") == "gamma_correction_answer" and source is not None:
            cell["source"] = source
    return nb


ANSWERS = {
    "ada": ('@student("mycourse.gamma_correction")\ndef gamma_correction(image, gamma, vmax=1.0):\n'
            "    return vmax * (np.asarray(image, dtype=np.float64) / vmax) ** gamma\n"),
    "bob": ('@student("mycourse.gamma_correction")\ndef gamma_correction(image, gamma, vmax=1.0):\n'
            "    return vmax * (np.asarray(image, dtype=np.float64) / vmax) ** (1 / gamma)\n"),
    "cyd": ("from mycourse.gamma_correction import gamma_correction as reference\n\n"
            '@student("mycourse.gamma_correction")\ndef gamma_correction(image, gamma, vmax=1.0):\n'
            "    return reference(image, gamma, vmax)\n"),
    "dan": None,  # the release as it is
}


@pytest.fixture(scope="module")
def graded(example_site, tmp_path_factory):
    """A project with one chapter (the set-up cell of lectures/ch02 and no exercise), the
    finished package of the how-to next to it; the how-to's steps 4 and 5 run in it."""
    from cvkit.course import Course

    project = tmp_path_factory.mktemp("project")
    (project / "autograders").mkdir()
    shutil.copy(ROOT / "autograders" / "nbgrader_config.py", project / "autograders" / "nbgrader_config.py")
    (project / "autograders" / "plan.toml").write_text(f'[[assignment]]\nid = "{CHAPTER}"\n')
    chapter = json.loads((ROOT / "lectures" / CHAPTER / f"{CHAPTER}.ipynb").read_text())
    setup = next(c for c in chapter["cells"] if c["cell_type"] == "code")
    chapter["cells"] = [{"cell_type": "markdown", "id": "title", "metadata": {}, "source": "# Chapter 2"}, setup]
    (project / "lectures" / CHAPTER).mkdir(parents=True)
    (project / "lectures" / CHAPTER / f"{CHAPTER}.ipynb").write_text(json.dumps(chapter))
    shutil.copytree(EXAMPLE, project / "mycourse-course", ignore=IGNORED)
    project.chmod(0o755)
    with _installed(example_site), pytest.MonkeyPatch.context() as patch:
        patch.chdir(project)
        exec(_blocks("python")[2], {})  # step 4: the cells into the chapter notebook
        assert main(_argv(BUILD)) == 0
        course = Course(project=project)
        release = json.loads(course.release_notebooks(CHAPTER)[0].read_text())
        for student, source in ANSWERS.items():
            course.submit(student, CHAPTER, {f"{CHAPTER}.ipynb": _answer(release, source)})
        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            status = main(_argv(GRADE))
        scores = {student: {e.name: e for e in entries} for student, entries in course.scores(CHAPTER).items()}
    return status, out.getvalue(), release, scores


@pytest.mark.slow
def test_the_release_hides_the_solution_and_the_hidden_tests(graded):
    _, _, release, _ = graded
    text = json.dumps(release)
    assert "### BEGIN SOLUTION" not in text and "normalised ** gamma" not in text
    assert "raise NotImplementedError()" in text and "hidden=True" not in text
    assert 'check(\\"mycourse.gamma_correction\\", gamma_correction)' in text


@pytest.mark.slow
def test_graded_through_the_pipeline_with_exact_scores(graded):
    status, out, _, scores = graded
    assert status == 0 and set(scores) == set(ANSWERS), out
    exercise = {student: scores[student]["gamma_correction"] for student in ANSWERS}
    assert {s: (e.score, e.max_score) for s, e in exercise.items()} == {
        "ada": (3.0, 3.0), "bob": (0.0, 3.0), "cyd": (0.0, 3.0), "dan": (0.0, 3.0)}
    assert exercise["bob"].mistakes == ["1/gamma instead of gamma"]
    assert exercise["ada"].mistakes == [] and exercise["ada"].flags == []
    assert any("import mycourse.gamma_correction (not allowed in graded code)" in flag
               for entry in scores["cyd"].values() for flag in entry.flags)
    assert "mistake “1/gamma instead of gamma”" in out  # what the checks found, under the grade table
    assert "import mycourse.gamma_correction (not allowed in graded code)" in out  # flagged for the instructor
