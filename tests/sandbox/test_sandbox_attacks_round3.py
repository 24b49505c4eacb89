"""The attack suite, round 3: what a third red team found, each attack replayed on the trusted path.

- A notebook's cells could fill a table with the clean pictures ``filters.denoise`` is measured
  on (the cases are refused them, the cells were not; so could another exercise's case) and
  "denoise" by looking the crop up: now the calls that may not use a source the cells or other
  cases loaded run again alone, with cells that get it blank, so the table holds zeros — while
  a function that does not depend on it keeps its grade, even when a demo line loading the
  picture sits before its definition.
- ``return None`` earned the hidden cases whose answer is None (training never stops, no board
  in the picture): a case whose answer needs no computing now counts only beside one that
  tells something.
- An output of booleans passed every check that compares with ``Close`` where numbers were
  expected: see ``tests/grading/test_mask_outputs.py``.
"""

import numpy as np
import pytest

from cvkit import data
from cvkit.course.trusted import grade_notebook
from cvkit.grading.runtime.wire import BoxCall
from cvkit.sandbox import session as sandbox

from course_helpers import exercise_cells, new_cell, new_notebook, submitted

pytestmark = pytest.mark.slow


CELLS = ["import numpy as np",
         # a demo line loading a picture, then the definitions: a lookup table and an honest function
         "from cvkit import data\nSTEP = data.step_signal(5)\n"
         "def looks_up(x):\n    return STEP\n"
         "def doubles(x):\n    return np.asarray(x) * 2.0\n"]


def test_a_table_of_data_loaded_by_a_cell_is_blank_where_the_exercise_may_not_use_that_data(bubblewrap):
    withheld = ("data.camera",)   # a case that may load the camera, not the step signal
    calls = [BoxCall("looks_up", args=(np.ones(2),), time_limit=20.0, allowed=withheld),
             BoxCall("doubles", args=(np.ones(2),), time_limit=20.0, allowed=withheld),
             BoxCall("looks_up", args=(np.ones(2),), time_limit=20.0, allowed=("data.step_signal",))]
    result = sandbox.run_calls(CELLS, calls)
    looked_up, doubled, allowed = result.outcomes
    assert looked_up.ok and np.array_equal(looked_up.value, np.zeros_like(data.step_signal(5)))
    assert doubled.ok and np.array_equal(doubled.value, [2.0, 2.0])   # defined after the load: still there
    assert allowed.ok and np.array_equal(allowed.value, data.step_signal(5))
    assert not result.crashed and not result.cell_errors, result.cell_errors


def test_cells_that_load_nothing_withheld_are_run_once(bubblewrap, monkeypatch):
    runs = []
    original = sandbox._Run.prepare

    def counted(*args, **kwargs):
        runs.append(args[1])
        return original(*args, **kwargs)

    monkeypatch.setattr(sandbox._Run, "prepare", classmethod(lambda cls, *a, **k: counted(*a, **k)))
    result = sandbox.run_calls(CELLS, [BoxCall("doubles", args=(np.ones(2),), time_limit=20.0,
                                               allowed=("data.step_signal",))])
    assert result.outcomes[0].ok and len(runs) == 1
    runs.clear()
    sandbox.run_calls(CELLS, [BoxCall("doubles", args=(np.ones(2),), time_limit=20.0, allowed=("data.camera",))])
    assert len(runs) == 2   # the step signal was loaded by a cell and is not this exercise's


def test_data_another_exercises_case_loaded_is_not_there_for_an_exercise_that_may_not_use_it(bubblewrap):
    cells = ["import numpy as np\nfrom cvkit import data\n"
             "def stashes(x):\n    global STOLEN\n    STOLEN = data.step_signal(5)\n    return np.asarray(x)\n"
             "def uses(x):\n    return STOLEN\n"]
    result = sandbox.run_calls(cells, [BoxCall("stashes", args=(np.ones(2),), time_limit=20.0,
                                               allowed=("data.step_signal",)),
                                       BoxCall("uses", args=(np.ones(2),), time_limit=20.0, allowed=("data.camera",))])
    stashed, used = result.outcomes
    assert stashed.ok
    assert not used.ok and used.exception == "NameError"   # run again alone: nothing was stashed there


# ------------------------------------------------- answers that need no computing earn nothing alone
STOPPING = {
    "constant": '@student("train.early_stopping")\ndef early_stopping(val_losses, patience):\n    return None',
    "honest": '@student("train.early_stopping")\ndef early_stopping(val_losses, patience):\n'
              '    losses = np.asarray(val_losses, dtype=float)\n'
              '    for i in range(len(losses)):\n'
              '        if i - int(np.argmin(losses[:i + 1])) >= patience:\n'
              '            return i\n'
              '    return None',
}


def _stopping_notebook(answer):
    cells = [new_cell("import numpy as np\nfrom cvkit.grading import check\nfrom cvkit.registry import student", "setup")]
    cells += exercise_cells("train.early_stopping", "early_stopping", answer)
    return new_notebook(cells)


def test_a_constant_none_earns_nothing_from_the_hidden_cases_whose_answer_is_none(bubblewrap):
    """``return None`` is the right answer of every hidden case in which training never stops
    (3 of 11 for early stopping, 4 of 13 "no board" cases for the corner finder): such cases
    count only beside a hidden case that tells something."""
    release = _stopping_notebook("### BEGIN SOLUTION\n" + STOPPING["honest"] + "\n### END SOLUTION")
    graded = {}
    for name, answer in STOPPING.items():
        result = grade_notebook(submitted(release, {"early_stopping_answer": answer}), student="sam", salt="round-3",
                                source_notebook=release)
        graded[name] = next(report for _, report in result.reports["early_stopping_hidden"])
    constant, honest = graded["constant"], graded["honest"]
    assert honest.score == 1
    assert any(case.message.startswith("passes, but its answer needs no computing") for case in constant.cases)
    assert constant.score == 0


def test_which_answers_need_no_computing():
    from cvkit.course.trusted import _trivial
    from cvkit.grading import Case

    image = np.arange(6.0).reshape(2, 3)
    case = Case((image, 1), {}, "an image and a size")
    for answer in (None, 0, 0.0, False, np.float64(0.0), np.zeros((2, 3)), image.copy()):
        assert _trivial(case, answer), answer
    for answer in (1, 0.5, True, (0, 0), image + 1, np.array([0.0, 2.0])):
        assert not _trivial(case, answer), answer
