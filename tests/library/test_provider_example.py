"""The example provider package under examples/: installed with pip, found through its entry
point, used by cvkit's pipelines, and graded against the reference."""
import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import cvkit
from cvkit import registry
from cvkit.grading import evaluate

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "cvkit-scipy-provider"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    site = tmp_path_factory.mktemp("site")
    done = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(site),
                           str(EXAMPLE)], capture_output=True, text=True)
    if done.returncode != 0:
        pytest.fail(f"pip could not install the example provider:\n{done.stderr[-2000:]}")
    return site


@pytest.fixture
def provider(installed, monkeypatch):
    monkeypatch.syspath_prepend(str(installed))
    registry.reload_plugins()
    yield registry.provider("scipy")
    monkeypatch.undo()
    registry.reload_plugins()


def test_discovered_through_its_entry_point(provider):
    assert "scipy" in registry.providers() and "scipy" not in registry.plugin_errors()
    for algorithm_id, function in provider.functions.items():  # checked against the references
        assert registry.signature_differences(registry.get(algorithm_id).reference, function) == []
    assert set(provider.functions) == {"filters.gaussian", "filters.median", "filters.correlate"}
    assert "cvkit-scipy-provider" in provider.origin


def test_pipelines_use_it_and_fall_back(provider):
    image = np.random.default_rng(0).random((20, 24))
    calls = []
    original = provider.functions["filters.correlate"]
    provider.functions["filters.correlate"] = lambda *a, **k: calls.append(1) or original(*a, **k)
    try:
        with cvkit.use("scipy"):
            out = cvkit.filters.mean(image, 5, border="reflect")  # cvkit's mean on the provider's correlate
            assert registry.implementation("filters.bilateral") is cvkit.filters.bilateral
    finally:
        provider.functions["filters.correlate"] = original
    assert calls == [1]
    np.testing.assert_allclose(out, cvkit.filters.mean(image, 5, border="reflect"), atol=1e-12)


@pytest.mark.parametrize("algorithm_id", ["filters.gaussian", "filters.median", "filters.correlate"])
def test_provider_functions_pass_the_checks(provider, algorithm_id):
    check = registry.get(algorithm_id).check
    lenient = dataclasses.replace(check, allowed_libraries=("scipy.ndimage",))
    function = provider.functions[algorithm_id]
    public = evaluate(algorithm_id, function, check=lenient)
    if algorithm_id == "filters.correlate":  # the example supports output="same" only
        assert all(c.passed for c in public.cases if "valid" not in c.description)
    else:
        assert public.passed, public.text()
        assert evaluate(algorithm_id, function, check=lenient, hidden=True, seed=1).passed
    # with the default check, SciPy is off limits: the provider is not a student's answer
    assert not evaluate(algorithm_id, function).passed
