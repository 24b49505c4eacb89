"""`pip install cvkit` is lean: NumPy and SciPy only, SciPy imported when a function needs it,
and the course's tools (nbgrader, JupyterLab, matplotlib, ...) never imported by the library."""
from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

from cvkit import registry

ROOT = Path(__file__).resolve().parents[2]
COURSE_TOOLS = ("scipy", "matplotlib", "nbgrader", "jupyter", "jupyterlab", "tqdm", "skimage", "sklearn",
                "nbconvert", "nbformat", "nh3", "copydetect", "dask")


def test_the_install_requires_numpy_and_scipy_only():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    names = sorted(d.split(">")[0].split("=")[0].split("[")[0].strip() for d in project["dependencies"])
    assert names == ["numpy", "scipy"]
    extras = project["optional-dependencies"]
    assert {"data", "learn", "course", "test"} <= set(extras)
    assert any(d.startswith("nbgrader") for d in extras["course"])


def test_importing_the_library_imports_no_scipy_and_no_course_tool():
    modules = ["cvkit"] + [f"cvkit.{topic}" for topic in registry.topic_modules()] + ["cvkit.data"]
    code = (f"import sys\nimport {', '.join(modules)}\n"
            f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({COURSE_TOOLS!r})))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "[]", f"imported at import time: {done.stdout.strip()}"


def test_the_fft_route_needs_no_scipy():
    """A 31×31 kernel on a 200×200 image takes correlate's FFT route, NumPy's FFT
    (``cvkit._fft``): scipy.fft is not imported; the result equals the direct sum on a window."""
    code = ("import sys, numpy as np\nfrom cvkit import filters\n"
            "before = 'scipy.fft' in sys.modules\n"
            "rng = np.random.default_rng(0); image, kernel = rng.random((200, 200)), rng.random((31, 31))\n"
            "out = filters.correlate(image, kernel, border='zero')\n"
            "direct = float((image[85:116, 85:116] * kernel).sum())\n"
            "print(before, 'scipy.fft' in sys.modules, abs(out[100, 100] - direct) < 1e-9)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.split() == ["False", "False", "True"]


def _extras_closure(extras: dict[str, list[str]], name: str) -> set[str]:
    """``name`` and every extra it brings along through ``cvkit[...]`` requirements."""
    found, todo = set(), [name]
    while todo:
        extra = todo.pop()
        if extra in found:
            continue
        found.add(extra)
        for requirement in extras.get(extra, []):
            if requirement.replace(" ", "").startswith("cvkit["):
                todo += requirement.split("[", 1)[1].split("]", 1)[0].split(",")
    return found


def test_a_course_gets_what_every_chapter_needs_and_the_scripts_know_it():
    """``cvkit[course]`` (what ``scripts/demo`` and ``scripts/lab`` install, and a course's hub)
    brings the sample images (``data``) and Chapters 9-12's digits (``learn``: scikit-learn);
    ``scripts/_venv.py``'s record of what each extra brings along is pyproject.toml's."""
    import importlib.util

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert {"course", "data", "learn"} <= _extras_closure(extras, "course")
    assert any(d.startswith("scikit-learn") for d in extras["learn"])
    spec = importlib.util.spec_from_file_location("cvkit_scripts_venv", ROOT / "scripts" / "_venv.py")
    venv = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(venv)
    for extra, brought in venv._INCLUDES.items():
        assert brought == _extras_closure(extras, extra), extra
    for script in ("demo", "lab"):
        assert 'extras="course"' in (ROOT / "scripts" / script).read_text(), script
