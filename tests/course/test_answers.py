"""cvkit.grading.answers.load_answers: a student's answers from another notebook of theirs."""
import json

import pytest

from cvkit import registry
from cvkit.grading.answers import AnswersUnavailable, load_answers

SETUP = "%matplotlib inline\nimport numpy as np\nfrom cvkit.registry import student\n"


def _cell(source, **nbgrader):
    cell = {"cell_type": "code", "execution_count": None, "metadata": {}, "outputs": [], "source": source}
    if nbgrader:
        cell["metadata"]["nbgrader"] = {"schema_version": 3, **nbgrader}
    return cell


def _answer(grade_id, source):
    return _cell(source, grade=False, grade_id=grade_id, locked=False, solution=True)


def _notebook(path, *answers, setup=SETUP):
    cells = [_cell(setup, grade=False, grade_id="setup", locked=True, solution=False),
             {"cell_type": "markdown", "metadata": {}, "source": "# A chapter"}]
    cells += list(answers)
    cells.append(_cell('check("nn.relu_forward", relu_forward)', grade=True, grade_id="relu_forward_visible",
                       locked=True, solution=False, points=1))
    path.write_text(json.dumps({"cells": cells, "metadata": {}, "nbformat": 4, "nbformat_minor": 4}))
    return path


RELU = '''@student("nn.relu_forward")
def relu_forward(x):
    """ReLU."""
    x = np.asarray(x, dtype=float)
    return np.maximum(x, 0), {"x": x}
'''
LINEAR = '''@student("nn.linear_forward")
def linear_forward(x, W, b):
    return helper(x, W) + b, {"x": x, "W": W, "b": b}
'''
HELPER = "def helper(x, W):\n    return np.asarray(x) @ np.asarray(W)\n"
STUB = '''@student("nn.relu_backward")
def relu_backward(dout, cache):
    """Backward."""
    # YOUR CODE HERE
    raise NotImplementedError()
'''


@pytest.fixture
def student_provider():
    """The student provider, restored after the test."""
    prov = registry.provider(registry.STUDENT)
    saved = dict(prov.functions), dict(prov.sources)
    for algorithm_id in list(prov.functions):
        prov.remove(algorithm_id)
    yield prov
    prov.clear()
    prov.functions.update(saved[0])
    prov.sources.update(saved[1])


def test_registers_the_answers_of_another_notebook(tmp_path, student_provider):
    path = _notebook(tmp_path / "ch10.ipynb", _answer("relu_forward_answer", RELU),
                     _answer("helper_answer", HELPER), _answer("linear_forward_answer", LINEAR))
    assert load_answers(path) == ["nn.linear_forward", "nn.relu_forward"]
    relu = student_provider.functions["nn.relu_forward"]
    assert relu([-1.0, 2.0])[0].tolist() == [0.0, 2.0]
    # helpers of other answer cells and the notebook's imports are in the answers' namespace
    assert student_provider.functions["nn.linear_forward"]([[1.0, 2.0]], [[1.0], [1.0]], 0.5)[0].tolist() == [[3.5]]
    import cvkit

    with cvkit.use("student"):
        assert registry.implementation("nn.relu_forward") is relu


def test_ids_keep_only_what_is_needed_and_ignore_other_stubs(tmp_path, student_provider):
    path = _notebook(tmp_path / "ch10.ipynb", _answer("relu_forward_answer", RELU),
                     _answer("relu_backward_answer", STUB),
                     _answer("broken_answer", '@student("learn.kmeans")\ndef kmeans(X, k):\n    pass\n1 / 0\n'))
    assert load_answers(str(path), ids=["nn.relu_forward"]) == ["nn.relu_forward"]
    assert set(student_provider.functions) == {"nn.relu_forward"}


def test_absent_notebook_is_one_line(tmp_path, student_provider):
    with pytest.raises(AnswersUnavailable) as info:
        load_answers(tmp_path / "missing" / "ch10.ipynb")
    message = str(info.value)
    assert "\n" not in message and "not there" in message and "ch10.ipynb" in message
    assert info.value._render_traceback_() == [f"\x1b[0;31mAnswersUnavailable\x1b[0m: {message}"]
    assert not student_provider.functions


def test_default_path_is_chapter_10_next_to_this_chapter(tmp_path, monkeypatch, student_provider):
    (tmp_path / "ch12_training").mkdir()
    (tmp_path / "ch10_representations").mkdir()
    _notebook(tmp_path / "ch10_representations" / "ch10_representations.ipynb", _answer("relu_forward_answer", RELU))
    monkeypatch.chdir(tmp_path / "ch12_training")
    assert load_answers(ids=["nn.relu_forward"]) == ["nn.relu_forward"]


def test_stub_is_one_line_and_registers_nothing(tmp_path, student_provider):
    path = _notebook(tmp_path / "ch10.ipynb", _answer("relu_forward_answer", RELU),
                     _answer("relu_backward_answer", STUB))
    for ids in (None, ["nn.relu_forward", "nn.relu_backward"]):
        with pytest.raises(AnswersUnavailable) as info:
            load_answers(path, ids=ids)
        assert "\n" not in str(info.value)
        assert "not answered yet: nn.relu_backward" in str(info.value)
        assert not student_provider.functions


def test_missing_id_and_raising_cell(tmp_path, student_provider):
    path = _notebook(tmp_path / "ch10.ipynb", _answer("relu_forward_answer", RELU + "raise ValueError('oops\\nmore')\n"))
    with pytest.raises(AnswersUnavailable, match="no answer cell registers nn.conv2d_forward"):
        load_answers(path, ids=["nn.conv2d_forward"])
    with pytest.raises(AnswersUnavailable) as info:
        load_answers(path, ids=["nn.relu_forward"])
    assert str(info.value).endswith("the cell of nn.relu_forward (cell 2) raises ValueError: oops")
    assert not student_provider.functions


def test_failure_restores_earlier_registrations(tmp_path, student_provider):
    def mine(x):
        return x

    registry.student("nn.relu_forward")(mine)
    path = _notebook(tmp_path / "ch10.ipynb", _answer("relu_forward_answer", RELU),
                     _answer("linear_forward_answer", LINEAR + "undefined_name\n"))
    with pytest.raises(AnswersUnavailable, match="NameError"):
        load_answers(path)
    assert student_provider.functions == {"nn.relu_forward": mine}


def test_unreadable_notebook_and_bad_arguments(tmp_path, student_provider):
    bad = tmp_path / "bad.ipynb"
    bad.write_text("{not json")
    with pytest.raises(AnswersUnavailable, match="cannot be read"):
        load_answers(bad)
    with pytest.raises(TypeError, match="ids"):
        load_answers(bad, ids="nn.relu_forward")
    with pytest.raises(TypeError, match="path"):
        load_answers(3)
