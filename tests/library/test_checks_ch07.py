"""The Chapter 7 checks are worth their points (the tests every chapter owes:
``checks_harness.ChapterChecks``; a mistake may call every Ch. 7 id), the comparators say what
is wrong, and the guard catches what it should on the checks as registered."""
from __future__ import annotations

import numpy as np
import pytest

import cvkit.camera
from cvkit import registry
from cvkit.camera.checks import FloatClose, Parts
from cvkit.grading import evaluate

import alternatives_ch07 as alt
import checks_harness as harness
from checks_harness import SEEDS, hidden_cases

CH07 = [f"camera.{name}" for name in cvkit.camera.__all__]


def _reprs(case):
    """The values of a case's arguments as text (arrays, lists and tuples through ``tolist``)."""
    return tuple(repr(np.asarray(v, dtype=object).tolist()) if isinstance(v, (np.ndarray, list, tuple)) else repr(v)
                 for v in list(case.args) + list(case.kwargs.values()))


class TestChapter07(harness.ChapterChecks):
    IDS = CH07
    ALTERNATIVES = alt.ALTERNATIVES
    EXTRA_ALTERNATIVES = alt.EXTRA_ALTERNATIVES

    def fingerprint(self, case):
        return _reprs(case)


# --------------------------------------------------------------------------------------------
# the shape of every check
# --------------------------------------------------------------------------------------------
def test_every_catalog_id_of_the_chapter_is_registered_with_its_section():
    sections = {
        "to_homogeneous": "7.4.1", "from_homogeneous": "7.4.1", "intrinsic_matrix": "7.5.2",
        "rotation_matrix": "7.3", "extrinsic_matrix": "7.5.3", "projection_matrix": "7.6", "project": "7.6",
        "decompose_projection": "7.6.1", "distort": "7.7.2", "undistort_points": "7.7", "project_full": "7.7.3",
    }
    assert set(cvkit.camera.__all__) == set(sections)
    for name, section in sections.items():
        record = registry.get(f"camera.{name}")
        assert record.section == section and record.reference is getattr(cvkit.camera, name)


def _arrays(case):
    return [np.asarray(v) for v in case.args if isinstance(v, np.ndarray)]


@pytest.mark.parametrize("algorithm_id", CH07)
def test_hidden_cases_include_awkward_inputs(algorithm_id):
    """Integer dtypes and single points wherever points or matrices go in."""
    for seed in SEEDS:
        cases = hidden_cases(algorithm_id, seed)
        if algorithm_id in ("camera.intrinsic_matrix", "camera.rotation_matrix"):
            assert any(all(isinstance(a, (int, np.integer)) for a in c.args) for c in cases)
            continue
        assert any(a.dtype.kind in "iu" for c in cases for a in _arrays(c)), "no integer input"
        if algorithm_id not in ("camera.extrinsic_matrix", "camera.projection_matrix", "camera.decompose_projection"):
            assert any(np.ndim(c.args[-1 if algorithm_id == "camera.project" else 0]) == 1
                       or np.shape(c.args[-1 if algorithm_id == "camera.project" else 0])[0] == 1 for c in cases)


@pytest.mark.parametrize("algorithm_id", ["camera.distort", "camera.undistort_points", "camera.project_full"])
def test_hidden_cases_use_every_number_of_coefficients(algorithm_id):
    for seed in SEEDS:
        cases = hidden_cases(algorithm_id, seed)
        index = 4 if algorithm_id == "camera.project_full" else 1
        lengths = {np.size(c.args[index]) for c in cases if len(c.args) > index}
        assert lengths == {1, 2, 3}
        tangential = [np.any(np.asarray(c.args[index + 1]) != 0) for c in cases if len(c.args) > index + 1]
        assert any(tangential) and not all(tangential)


def test_hidden_cases_of_decompose_use_both_signs_and_extreme_scales():
    for seed in SEEDS:
        dets = [np.linalg.det(np.asarray(c.args[0], dtype=float)[:, :3]) for c in hidden_cases("camera.decompose_projection", seed)]
        assert any(d > 0 for d in dets) and any(d < 0 for d in dets)
        scales = [abs(d) ** (1 / 3) for d in dets]
        assert min(scales) < 1e-3 and max(scales) > 1e7


def test_hidden_cases_of_project_include_infinity_and_homogeneous_input():
    for seed in SEEDS:
        cases = hidden_cases("camera.project", seed)
        outputs = [cvkit.camera.project(*c.args) for c in cases]
        assert any(np.asarray(c.args[1]).shape[1] == 4 and np.any(np.asarray(c.args[1])[:, 3] == 0) for c in cases)
        assert any(not np.all(np.isfinite(o)) for o in outputs)
        dets = [np.linalg.det(np.asarray(c.args[0], dtype=float)[:, :3]) for c in cases]
        assert any(d < 0 for d in dets)


# --------------------------------------------------------------------------------------------
# the comparators
# --------------------------------------------------------------------------------------------
def test_float_close_wants_float_where_float_is_expected():
    compare = FloatClose(rtol=0.0, atol=0.0)
    expected = np.array([[1.0, 2.0, 1.0]])
    as_int = np.array([[1, 2, 1]])
    mismatch = compare(as_int, expected)
    assert mismatch is not None and "dtype" in mismatch.message and "int64" in mismatch.message
    assert compare(as_int, as_int.copy()) is None          # an integer mistake can still be named
    assert compare(expected.copy(), expected) is None
    assert "Mismatched" in compare(expected + 1, expected).details   # numpy.testing wording: the details
    assert compare(expected + 1, expected).message.startswith("all 3 values differ")
    inf = np.array([np.inf, np.nan, -np.inf])
    assert compare(inf.copy(), inf) is None
    assert compare(np.array([np.inf, np.nan, np.inf]), inf) is not None


def test_parts_names_the_wrong_part():
    compare = Parts(names=("A", "R", "t"), inner=FloatClose(rtol=1e-7, atol=1e-8))
    expected = (np.eye(3), np.eye(3), np.zeros(3))
    assert compare(tuple(e.copy() for e in expected), expected) is None
    wrong = (np.eye(3), -np.eye(3), np.zeros(3))
    assert compare(wrong, expected).message.startswith("R: ")
    assert "tuple (A, R, t)" in compare(np.eye(3), expected).message
    assert "tuple of 2" in compare((np.eye(3), np.eye(3)), expected).message


def test_a_failing_report_shows_the_part_and_the_hint():
    def decompose_projection(P):  # forgets A⁻¹ for t
        A, R, t = alt.decompose_projection(P)
        M = np.asarray(P, dtype=float)[:, :3]
        lam = np.sign(np.linalg.det(M)) * np.linalg.norm(M[2])
        return A, R, np.asarray(P, dtype=float)[:, 3] / lam

    report = evaluate("camera.decompose_projection", decompose_projection)
    assert not report.passed and report.mistake == "t read off the last column (A⁻¹ not applied)"
    assert any(c.message.startswith("t: ") for c in report.cases if not c.passed)
    assert "solve" in report.text()


# --------------------------------------------------------------------------------------------
# the guard on Chapter 7 checks (as registered)
# --------------------------------------------------------------------------------------------
def test_opencv_is_forbidden_and_named():
    cv2 = pytest.importorskip("cv2")

    def project_full(points_world, A, R, t, k=(0.0, 0.0, 0.0), p=(0.0, 0.0)):
        k = list(np.atleast_1d(k)) + [0.0, 0.0]
        out, _ = cv2.projectPoints(np.asarray(points_world, dtype=float), cv2.Rodrigues(np.asarray(R, dtype=float))[0],
                                   np.asarray(t, dtype=float).reshape(3), np.asarray(A, dtype=float),
                                   np.array([k[0], k[1], p[0], p[1], k[2]], dtype=float))
        return out[:, 0]

    harness.assert_scores_zero("camera.project_full", project_full, "cv2", every_case=True)


def test_calling_the_reference_is_forbidden_but_building_blocks_are_allowed():
    def project(P, points_world):
        return cvkit.camera.project(P, points_world)

    report = evaluate("camera.project", project, hidden=True, seed=SEEDS[0])
    assert report.score == 0.0 and "'camera.project'" in report.cases[0].message

    def project_via_blocks(P, points_world):
        pts = np.asarray(points_world, dtype=float)
        if pts.shape[1] == 3:
            pts = cvkit.camera.to_homogeneous(pts)
        return cvkit.camera.from_homogeneous(pts @ np.asarray(P, dtype=float).T)

    harness.assert_passes_everywhere("camera.project", project_via_blocks, SEEDS)

    def project_full(points_world, A, R, t, k=(0.0, 0.0, 0.0), p=(0.0, 0.0)):
        cam = np.asarray(points_world, dtype=float) @ np.asarray(R, dtype=float).T + np.asarray(t, dtype=float).reshape(3)
        xy = cvkit.camera.distort(cam[:, :2] / cam[:, 2:], k, p)
        return cvkit.camera.from_homogeneous(cvkit.camera.to_homogeneous(xy) @ np.asarray(A, dtype=float).T)

    report = evaluate("camera.project_full", project_full)
    assert not report.passed and all("camera.to_homogeneous" in c.message for c in report.cases)


def test_modifying_the_input_fails():
    def from_homogeneous(points_h):
        points_h[..., :-1] /= points_h[..., -1:]   # in place: the caller's array changes
        return np.asarray(points_h[..., :-1], dtype=float)

    harness.assert_scores_zero("camera.from_homogeneous", from_homogeneous, "modified its input")


def test_integer_output_is_refused_and_named():
    def to_homogeneous(points):
        pts = np.asarray(points)
        return np.hstack([pts, np.ones_like(pts[..., :1])]) if pts.ndim == 2 else np.append(pts, np.ones_like(pts[:1]))

    report = evaluate("camera.to_homogeneous", to_homogeneous)
    assert not report.passed and report.mistake == "integer dtype kept (np.ones_like)"
    assert any("dtype" in c.message for c in report.cases if not c.passed)
