"""The execution step of autograding (cvkit.sandbox.notebook_run): nbgrader's sanitizing rules,
then a run that records errors, goes on after them and interrupts a cell past its limit."""
import copy
import itertools
import json
import subprocess
import sys

from cvkit.course.notebook import prepare
from cvkit.sandbox.notebook_run import TIMEOUT_ERROR, execute


_IDS = itertools.count()


def _cell(source, grade_id=None, *, solution=False, grade=False, locked=False, outputs=None):
    meta = {}
    if grade_id:
        meta["nbgrader"] = {"grade_id": grade_id, "solution": solution, "grade": grade, "locked": locked,
                            "schema_version": 3}
        if grade:
            meta["nbgrader"]["points"] = 1
    return {"cell_type": "code", "id": f"cell-{next(_IDS)}", "source": source,
            "metadata": meta, "execution_count": 3 if outputs else None, "outputs": outputs or []}


FAKE_PASS = [{"output_type": "stream", "name": "stdout", "text": "all tests passed\n"}]


def _release():
    return {"nbformat": 4, "nbformat_minor": 5,
            "metadata": {"kernelspec": {"name": "python3", "display_name": "Python 3", "language": "python"}},
            "cells": [_cell("x = 1", "setup", locked=True),
                      _cell("# YOUR CODE HERE", "answer", solution=True),
                      _cell("assert answer() == 2", "answer_test", grade=True, locked=True)]}


def test_prepare_restores_locked_and_test_cells_and_clears_outputs():
    release = _release()
    submitted = copy.deepcopy(release)
    submitted["metadata"]["kernelspec"] = {"name": "evil", "display_name": "x", "language": "python"}
    submitted["cells"][0] = _cell("x = 2  # changed", "setup", locked=True, outputs=FAKE_PASS)
    submitted["cells"][1] = _cell("def answer():\n    return 2", "answer", solution=True, outputs=FAKE_PASS)
    submitted["cells"][2] = _cell("pass  # the test, emptied", "answer_test", grade=True, outputs=FAKE_PASS)
    submitted["cells"].append(_cell("print('mine')", outputs=FAKE_PASS))
    before = json.dumps(submitted, sort_keys=True)
    prepared = prepare(submitted, release)
    assert json.dumps(submitted, sort_keys=True) == before, "the submission must not be modified"
    sources = [c["source"] for c in prepared["cells"]]
    assert sources == ["x = 1", "def answer():\n    return 2", "assert answer() == 2", "print('mine')"]
    assert all(c["outputs"] == [] and c["execution_count"] is None for c in prepared["cells"])
    assert prepared["metadata"]["kernelspec"]["name"] == "python3"


def test_prepare_restores_a_test_cell_retyped_as_markdown():
    release = _release()
    submitted = copy.deepcopy(release)
    submitted["cells"][2] = {"cell_type": "markdown", "source": "nothing to see", "metadata": submitted["cells"][2]["metadata"]}
    prepared = prepare(submitted, release)
    assert prepared["cells"][2]["cell_type"] == "code" and prepared["cells"][2]["source"] == "assert answer() == 2"


def test_execute_records_errors_goes_on_and_interrupts_long_cells(tmp_path):
    nb = _release()
    nb["cells"] = [
        _cell("import os\nprint(os.environ.get('CVKIT_TRUSTED_GRADING'))"),
        _cell(["raise ValueError(", "'boom')"]),            # a multi-line source, as stored on disk
        _cell("import time\ntime.sleep(30)"),
        _cell("print('still running')"),
    ]
    done = execute(nb, str(tmp_path), timeout=3)
    outputs = [c["outputs"] for c in done["cells"]]
    assert outputs[1][0]["ename"] == "ValueError"
    assert outputs[2][-1]["ename"] in ("KeyboardInterrupt", TIMEOUT_ERROR["ename"])  # interrupted
    assert "".join(outputs[3][0]["text"]) == "still running\n"
    assert all(c["execution_count"] for c in done["cells"])


def test_command_line_marks_checks_as_decided_elsewhere(tmp_path):
    nb = _release()
    nb["cells"] = [_cell("import os\nprint(os.environ.get('CVKIT_TRUSTED_GRADING'))")]
    source, target = tmp_path / "in.ipynb", tmp_path / "out.ipynb"
    source.write_text(json.dumps(nb))
    subprocess.run([sys.executable, "-m", "cvkit.sandbox.notebook_run", str(source), str(target)], check=True,
                   capture_output=True, timeout=120)
    assert "".join(json.loads(target.read_text())["cells"][0]["outputs"][0]["text"]) == "1\n"
    bad = subprocess.run([sys.executable, "-m", "cvkit.sandbox.notebook_run", str(source)], capture_output=True, text=True)
    assert bad.returncode == 2 and "usage" in bad.stderr


def test_matplotlib_reads_a_font_list_made_once_and_kept_read_only(tmp_path, monkeypatch, grading_sandbox):
    """Each sandboxed run finds matplotlib's font list ready (no rebuild, no fontconfig error in
    the student's outputs), and no notebook can change it for the next one."""
    import pytest

    from cvkit.sandbox import notebook_run as execution

    assert grading_sandbox is None, grading_sandbox
    pytest.importorskip("matplotlib")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(execution, "_font_lists", {})
    code = ("import os, matplotlib.font_manager as fm\n"
            "names = [n for n in os.listdir(os.environ['MPLCONFIGDIR']) if n.startswith('fontlist')]\n"
            "try:\n"
            "    open(os.path.join(os.environ['MPLCONFIGDIR'], names[0]), 'w').write('{}')\n"
            "    print('changed')\n"
            "except OSError:\n"
            "    print('refused')\n"
            "print(len(names), len(fm.fontManager.ttflist) > 0)")
    notebook = dict(_release(), cells=[_cell(code)])
    files = {"a.ipynb": json.dumps(notebook).encode()}
    runs = [execution.execute_in_sandbox(files, "a.ipynb") for _ in range(2)]
    made = list((tmp_path / "cache" / "cvkit").glob("matplotlib-*/fontlist-*.json"))
    assert len(made) == 1
    content = made[0].read_bytes()
    json.loads(content)
    for executed, log in runs:
        assert executed is not None, log
        outputs = json.loads(executed)["cells"][0]["outputs"]
        assert [(o["name"], "".join(o["text"])) for o in outputs] == [("stdout", "refused\n1 True\n")], outputs
    assert made[0].read_bytes() == content
    assert execution.matplotlib_font_list()[0] == str(made[0])


def test_inline_figures_are_the_same_pixels_written_faster(tmp_path):
    """The grading kernel writes inline PNGs with zlib level 3 (not 6): the same pixels."""
    import base64
    import io

    import numpy as np
    import pytest

    Image = pytest.importorskip("PIL.Image")
    nb = _release()
    nb["cells"] = [_cell("%matplotlib inline\nimport matplotlib.pyplot as plt\nimport numpy as np\n"
                         "from IPython.core.pylabtools import print_figure\n"
                         "from matplotlib_inline.config import InlineBackend\n"
                         "print(InlineBackend.instance().print_figure_kwargs)\n"
                         "fig, ax = plt.subplots(figsize=(2, 2), dpi=50)\n"
                         "ax.imshow(np.arange(64.0).reshape(8, 8), cmap='gray')\n"
                         "import base64; default = base64.b64encode(print_figure(fig, 'png', bbox_inches='tight'))\n"
                         "print(default.decode())\n"
                         "plt.show()")]
    outputs = execute(nb, str(tmp_path), timeout=60)["cells"][0]["outputs"]
    text = "".join("".join(o["text"]) for o in outputs if o["output_type"] == "stream").split("\n")
    assert "'compress_level': 3" in text[0] and "'bbox_inches': 'tight'" in text[0]
    shown = [o["data"]["image/png"] for o in outputs if "image/png" in o.get("data", {})]
    assert len(shown) == 1

    def pixels(encoded):
        return np.asarray(Image.open(io.BytesIO(base64.b64decode(encoded))))

    assert np.array_equal(pixels(shown[0]), pixels(text[1]))
