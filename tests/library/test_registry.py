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


def _distribution(site, name, entry_points, modules):
    """A throwaway installed distribution in ``site``: dist-info with entry points, and modules."""
    dist = site / f"{name.replace('-', '_')}-1.0.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (dist / "entry_points.txt").write_text("".join(
        f"[{group}]\n" + "".join(f"{k} = {v}\n" for k, v in eps.items()) for group, eps in entry_points.items()))
    for filename, source in modules.items():
        (site / filename).write_text(textwrap.dedent(source))


def _on_path(monkeypatch, *sites):
    """``sites`` first on sys.path (in this order) while a test runs, entry points rediscovered."""
    for site in reversed(sites):
        monkeypatch.syspath_prepend(str(site))
    registry.reload_plugins()
    yield sites[0]
    monkeypatch.undo()
    registry.reload_plugins()


@pytest.fixture
def plugin_site(tmp_path, monkeypatch):
    """A throwaway distribution with entry points in the group cvkit.providers."""
    site = tmp_path / "site"
    _distribution(site, "cvkit-fakeprovider",
                  {"cvkit.providers": {"fakecv": "cvkit_fakeprovider:provides",
                                       "brokencv": "cvkit_brokenprovider:PROVIDES"}},
                  {"cvkit_fakeprovider.py": """\
                      import numpy as np
                      def triangle_kernel(sigma, radius=None):
                          return np.array([1.0, 2.0, 1.0]) / 4.0
                      def provides():
                          return {"filters.gaussian_kernel": triangle_kernel}
                      """,
                   "cvkit_brokenprovider.py": "raise ImportError('this plugin needs a GPU')\n"})
    yield from _on_path(monkeypatch, site)


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


# ------------------------------------------------------------------ validation of providers
def _gaussian(image, sigma, border="reflect101"):
    return image


@pytest.mark.parametrize("function, expected", [
    (_gaussian, []),
    (lambda *args, **kwargs: None, []),  # a generic wrapper
    (lambda image, sigma, border="reflect101", extra=1.0: None, []),  # extra parameter with a default
    (lambda img, sigma, border="reflect101": None, ["parameter 1 is 'img', the reference's is 'image'"]),
    (lambda sigma, image, border="reflect101": None, ["parameter 1 is 'sigma', the reference's is 'image'",
                                                      "parameter 2 is 'image', the reference's is 'sigma'"]),
    (lambda image, sigma, border: None, ["'border' has no default (the reference's is 'reflect101')"]),
    (lambda image, sigma, border="reflect": None, ["'border' defaults to 'reflect' (the reference's to 'reflect101')"]),
    (lambda image, sigma: None, ["parameter 'border' (position 3) is missing"]),
    (lambda image, sigma, border="reflect101", mode=None, *, scale: None,
     ["extra keyword parameter 'scale' has no default"]),
])
def test_signature_differences(function, expected):
    assert registry.signature_differences(cvkit.filters.gaussian, function) == expected


def test_register_provider_refuses_unknown_ids_and_other_signatures():
    with pytest.raises(ValueError) as info:
        registry.register_provider("typos", {"filters.gausian": _gaussian,
                                             "filters.median": lambda img, size, border="reflect101": img},
                                   origin="cvkit-typos 1.0")
    message = str(info.value)
    assert "provider 'typos' (cvkit-typos 1.0) refused" in message
    assert "'filters.gausian' is not a registered algorithm" in message and "did you mean 'filters.gaussian'" in message
    assert "filters.median: parameter 1 is 'img', the reference's is 'image'" in message
    with pytest.raises(KeyError, match="no provider called 'typos'"):
        registry.provider("typos")  # nothing was registered


COURSE = """\
    import numpy as np
    import cvkit
    from cvkit.grading import Case, Check, Mistake, close

    def _times_three(x):
        return 3.0 * np.asarray(x, dtype=float)

    CHECK = Check(public=[Case((np.array([1.0, 2.0]),), {}, "two values")],
                  hidden=lambda rng: [Case((rng.random(4),), {}, "random")],
                  compare=close(), mistakes=[Mistake("tripled", _times_three, "twice, not three times")])

    @cvkit.algorithm("fakecourse.double", section="1.1", check=CHECK)
    def double(x):
        '''Twice x.'''
        return 2.0 * np.asarray(x, dtype=float)
    """


@pytest.fixture
def course_site(tmp_path, monkeypatch):
    """Course packages (group cvkit.algorithms) and providers, good and bad, on sys.path."""
    site, later = tmp_path / "site", tmp_path / "later"  # `later` comes after `site` on sys.path
    site.mkdir()
    later.mkdir()
    algorithms = "cvkit.algorithms"
    _distribution(site, "cvkit-fakecourse", {algorithms: {"fakecourse": "fakecourse_pkg"}},
                  {"fakecourse_pkg.py": COURSE})
    _distribution(later, "cvkit-othercourse", {algorithms: {"fakecourse": "othercourse_pkg"}},
                  {"othercourse_pkg.py": """\
                      import cvkit
                      @cvkit.algorithm("fakecourse.double", section="9.9")
                      def double(x):
                          return x + x
                      """})
    _distribution(site, "cvkit-brokencourse", {algorithms: {"brokencourse": "brokencourse_pkg"}},
                  {"brokencourse_pkg.py": "raise ImportError('this course needs a GPU')\n"})
    _distribution(site, "cvkit-straycourse", {algorithms: {"stray": "stray_pkg"}},
                  {"stray_pkg.py": """\
                      import cvkit
                      @cvkit.algorithm("stray.fine", section="1")
                      def fine(x):
                          return x
                      @cvkit.algorithm("elsewhere.thing", section="1")
                      def thing(x):
                          return x
                      """})
    _distribution(site, "cvkit-clashcourse", {algorithms: {"clash": "clash_pkg"}},
                  {"clash_pkg.py": """\
                      import cvkit
                      @cvkit.algorithm("filters.gaussian", section="3.9.1")
                      def gaussian(image, sigma, border="reflect101"):
                          return image
                      """})
    _distribution(site, "cvkit-filterscourse", {algorithms: {"filters": "filters_pkg"}},
                  {"filters_pkg.py": "raise AssertionError('never imported')\n"})
    _distribution(site, "cvkit-badcheck", {algorithms: {"badcheck": "badcheck_pkg"}},
                  {"badcheck_pkg.py": """\
                      import numpy as np
                      import cvkit
                      from cvkit.grading import Case, Check, close

                      CHECK = Check(public=[Case((np.array([4.0]),), {}, "positive"),
                                            Case((np.array([-1.0]),), {}, "negative")],
                                    hidden=lambda rng: [], compare=close())

                      @cvkit.algorithm("badcheck.root", section="1", check=CHECK)
                      def root(x):
                          x = np.asarray(x, dtype=float)
                          if np.any(x < 0):
                              raise ValueError("x must be >= 0")
                          return np.sqrt(x)
                      """})
    _distribution(site, "cvkit-typoprovider", {"cvkit.providers": {"typo": "typo_provider:PROVIDES"}},
                  {"typo_provider.py": """\
                      def gaussian(image, sigma, border="reflect101"):
                          return image
                      PROVIDES = {"filters.gausian": gaussian}
                      """})
    _distribution(site, "cvkit-signatureprovider", {"cvkit.providers": {"otherargs": "signature_provider:PROVIDES"}},
                  {"signature_provider.py": """\
                      def gaussian(img, sigma, border="reflect"):
                          return img
                      PROVIDES = {"filters.gaussian": gaussian}
                      """})
    _distribution(site, "cvkit-courseprovider", {"cvkit.providers": {"fast": "course_provider:PROVIDES"}},
                  {"course_provider.py": """\
                      def double(x):
                          return x * 2.0
                      PROVIDES = {"fakecourse.double": double}
                      """})
    yield from _on_path(monkeypatch, site, later)


def test_course_package_is_found_through_its_entry_point(course_site):
    record = registry.get("fakecourse.double")
    assert record.section == "1.1" and record.reference(np.array([1.5]))[0] == 3.0
    assert record.package == "course package 'cvkit-fakecourse' (entry point fakecourse = fakecourse_pkg)"
    assert "fakecourse.double" in [a.id for a in registry.algorithms()]
    names = {(p.distribution, p.name) for p in registry.course_packages()}
    assert ("cvkit-fakecourse", "fakecourse") in names and ("cvkit-brokencourse", "brokencourse") in names


def test_course_check_grades_like_cvkit_own(course_site):
    from cvkit.grading import evaluate

    assert evaluate("fakecourse.double", lambda x: np.asarray(x) * 2.0).passed
    report = evaluate("fakecourse.double", lambda x: np.asarray(x) * 3.0, hidden=True, seed=1)
    assert report.score == 0.0 and report.mistake == "tripled"


def test_an_id_registered_by_two_packages_names_both(course_site):
    errors = registry.package_errors()
    assert "duplicate algorithm id 'fakecourse.double'" in errors["fakecourse"]
    assert "cvkit-fakecourse" in errors["fakecourse"] and "cvkit-othercourse" in errors["fakecourse"]
    assert registry.get("fakecourse.double").section == "1.1"  # the first one on sys.path stays


def test_refused_course_packages_are_reported_never_fatal(course_site):
    errors = registry.package_errors()
    assert "cvkit-brokencourse" in errors["brokencourse"] and "needs a GPU" in errors["brokencourse"]
    assert "'elsewhere.thing'" in errors["stray"] and "must start with 'stray.'" in errors["stray"]
    assert "cvkit-straycourse" in errors["stray"]
    with pytest.raises(KeyError, match="stray.fine"):  # the refused package's other ids are withdrawn too
        registry.get("stray.fine")
    assert "belongs to a cvkit module" in errors["filters"] and "cvkit-filterscourse" in errors["filters"]
    assert ("duplicate algorithm id 'filters.gaussian': registered by cvkit (cvkit.filters._linear.gaussian) and "
            "again by course package 'cvkit-clashcourse' (entry point clash = clash_pkg)") in errors["clash"]
    with pytest.raises(KeyError, match="needs a GPU"):
        registry.get("brokencourse.anything")
    assert registry.get("filters.gaussian").reference is cvkit.filters.gaussian


def test_check_whose_reference_fails_its_own_cases_is_refused(course_site):
    record = registry.get("badcheck.root")  # registering is fine: nothing runs at import
    with pytest.raises(ValueError) as info:
        record.check
    message = str(info.value)
    assert "course package 'cvkit-badcheck'" in message and "'badcheck.root' is refused" in message
    assert "public case 2 (negative): the reference raised ValueError: x must be >= 0" in message
    with pytest.raises(ValueError, match="cvkit-badcheck"):
        registry.validate("badcheck.root")
    from cvkit.grading import evaluate

    with pytest.raises(ValueError, match="is refused"):
        evaluate("badcheck.root", np.sqrt)


def test_validate_cvkit_own_check():
    assert registry.validate("filters.mean_kernel") == len(registry.get("filters.mean_kernel").check.public_cases())


def test_providers_for_unknown_ids_or_other_signatures_are_refused(course_site):
    errors = registry.plugin_errors()
    assert "cvkit-typoprovider" in errors["typo"] and "'filters.gausian' is not a registered algorithm" in errors["typo"]
    assert "did you mean 'filters.gaussian'" in errors["typo"]
    assert "cvkit-signatureprovider" in errors["otherargs"]
    assert "parameter 1 is 'img', the reference's is 'image'" in errors["otherargs"]
    assert "'border' defaults to 'reflect'" in errors["otherargs"]
    for name in ("typo", "otherargs"):
        assert name not in registry.providers()
        with pytest.raises(KeyError, match="failed to load"):
            with cvkit.use(name):
                pass
    assert "fakecourse.double" in registry.provider("fast")  # a course package's id can have providers too


def test_outside_cvkit_the_topic_namespaces_are_refused():
    def brand_new(image):
        return image

    with pytest.raises(ValueError, match="namespace 'filters' belongs to cvkit"):
        registry.algorithm("filters.brand_new", section="3.1")(brand_new)
    with pytest.raises(KeyError):
        registry.get("filters.brand_new")
