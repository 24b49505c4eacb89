"""The registry: metadata-only registration, lazy lookup, providers, entry points, fallback."""
import textwrap

import numpy as np
import pytest

import cvkit
from cvkit import registry


@pytest.fixture
def clean_student():
    yield registry.provider("student")
    registry.provider("student").clear()


def test_get_returns_record_with_metadata():
    record = registry.get("filters.gaussian")
    assert record.id == "filters.gaussian"
    assert record.section == "3.9.1"
    assert record.reference is cvkit.filters.gaussian
    assert record.check is not None
    assert record.module == "filters"


def test_algorithms_lists_chapter3_sorted():
    ids = [a.id for a in registry.algorithms()]
    assert ids == sorted(ids)
    for expected in ("filters.pad", "filters.nl_means", "noise.add_gaussian", "noise.add_salt_and_pepper"):
        assert expected in ids


def test_unknown_id_suggests_close_matches():
    with pytest.raises(KeyError, match="filters.gaussian"):
        registry.get("filters.gausian")


@pytest.mark.parametrize("bad", ["gaussian", "Filters.gaussian", "filters.", 3, "a.b.c"])
def test_malformed_id_is_a_clear_error(bad):
    with pytest.raises(ValueError, match="algorithm id"):
        registry.get(bad)


def test_decorator_records_metadata_only_and_returns_function():
    def f(x):
        return x

    decorated = registry.algorithm("testing.identity", section="0.1")(f)
    try:
        assert decorated is f
        assert registry.get("testing.identity").reference is f
    finally:
        registry._algorithms.pop("testing.identity", None)


def test_duplicate_id_names_both_sources():
    def other_gaussian(image, sigma, border="reflect101"):
        return image

    with pytest.raises(ValueError) as info:
        registry.algorithm("filters.gaussian", section="3.9.1")(other_gaussian)
    message = str(info.value)
    assert "filters.gaussian" in message
    assert "cvkit.filters._linear.gaussian" in message
    assert "other_gaussian" in message
    assert registry.get("filters.gaussian").reference is cvkit.filters.gaussian


def test_lazy_check_resolution():
    record = registry.get("filters.median")
    assert isinstance(record.check, cvkit.grading.Check)


def test_student_provider_and_fallback(clean_student):
    calls = []

    @cvkit.student("filters.gaussian_kernel")
    def box_kernel(sigma, radius=None):
        calls.append(sigma)
        return np.ones(3) / 3

    image = np.zeros((7, 7))
    image[3, 3] = 1.0
    with cvkit.use("student"):
        assert registry.active_provider() == "student"
        out = cvkit.filters.gaussian(image, 5.0)
        # median has no student version: the reference is used
        assert registry.implementation("filters.median") is cvkit.filters.median
    assert calls == [5.0]
    np.testing.assert_allclose(out[2:5, 2:5], np.full((3, 3), 1 / 9))
    assert registry.active_provider() == "reference"
    # outside the block the reference kernel is used again
    ref = cvkit.filters.gaussian(image, 5.0)
    assert not np.allclose(ref, out)


def test_student_redefinition_replaces(clean_student):
    @cvkit.student("filters.mean_kernel")
    def mean_kernel(size):
        return 1

    @cvkit.student("filters.mean_kernel")
    def mean_kernel(size):  # noqa: F811 - re-running the notebook cell
        return 2

    assert registry.provider("student").functions["filters.mean_kernel"](3) == 2


def test_provider_duplicate_from_two_sources_is_error():
    prov = registry.Provider("tmp")
    prov.add("filters.mean", lambda *a: 1, source="pkg_a.mean")
    with pytest.raises(ValueError, match="pkg_a.mean.*pkg_b.mean"):
        prov.add("filters.mean", lambda *a: 2, source="pkg_b.mean")


def test_use_unknown_provider():
    with pytest.raises(KeyError, match="no provider called 'nope'"):
        with cvkit.use("nope"):
            pass


@pytest.fixture
def plugin_site(tmp_path, monkeypatch):
    """A throwaway distribution with entry points in the group cvkit.providers."""
    site = tmp_path / "site"
    dist = site / "cvkit_fakeprovider-1.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: cvkit-fakeprovider\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text(textwrap.dedent("""\
        [cvkit.providers]
        fakecv = cvkit_fakeprovider:provides
        brokencv = cvkit_brokenprovider:PROVIDES
        """))
    (site / "cvkit_fakeprovider.py").write_text(textwrap.dedent("""\
        import numpy as np
        def triangle_kernel(sigma, radius=None):
            return np.array([1.0, 2.0, 1.0]) / 4.0
        def provides():
            return {"filters.gaussian_kernel": triangle_kernel}
        """))
    (site / "cvkit_brokenprovider.py").write_text("raise ImportError('this plugin needs a GPU')\n")
    monkeypatch.syspath_prepend(str(site))
    registry.reload_plugins()
    yield site
    monkeypatch.undo()
    registry.reload_plugins()


def test_entry_point_discovery(plugin_site):
    assert "fakecv" in registry.providers()
    prov = registry.provider("fakecv")
    assert "filters.gaussian_kernel" in prov
    assert "cvkit-fakeprovider" in prov.origin
    image = np.zeros((5, 5))
    image[2, 2] = 1.0
    with cvkit.use("fakecv"):
        out = cvkit.filters.gaussian(image, 3.0)
        assert registry.implementation("filters.median") is cvkit.filters.median  # fallback
    expected = np.outer([1, 2, 1], [1, 2, 1]) / 16.0
    np.testing.assert_allclose(out[1:4, 1:4], expected)


def test_broken_plugin_is_reported_not_fatal(plugin_site):
    errors = registry.plugin_errors()
    assert "brokencv" in errors
    assert "needs a GPU" in errors["brokencv"]
    assert "brokencv" not in registry.providers()
    with pytest.raises(KeyError, match="failed to load.*needs a GPU"):
        with cvkit.use("brokencv"):
            pass
    # everything else keeps working
    assert registry.get("filters.gaussian").section == "3.9.1"


def test_cli_list_reports_plugins(plugin_site, capsys):
    from cvkit.cli import main

    assert main(["list"]) == 0
    out = capsys.readouterr().out
    assert "filters.gaussian" in out and "3.9.1" in out
    assert "brokencv" in out and "failed to load" in out
