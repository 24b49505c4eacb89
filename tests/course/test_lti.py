"""cvkit course push --lti (cvkit.course.lti) against a local LTI 1.3 platform (tests/course/lti_platform.py)
that verifies the signed client assertion and the scopes, and records the JSON it receives."""
from __future__ import annotations

import pytest

from cvkit.course import lti
from cvkit.course.lti import load_config, push
from lti_platform import CONTAINER, LINEITEM, SCORE, SCOPE_LINEITEM, SCOPE_SCORE, Platform, new_key
from test_lms import sheet

ROSTER = "student_id,lti_user_id\nada,u-ada\nbob,u-bob\ncyd,u-cyd\nzoë,u-zoe\nnina,u-nina\n"


@pytest.fixture(autouse=True)
def no_proxy(monkeypatch):
    for name in ("http_proxy", "HTTP_PROXY", "https_proxy", "HTTPS_PROXY", "all_proxy", "ALL_PROXY"):
        monkeypatch.delenv(name, raising=False)


@pytest.fixture(scope="module")
def key():
    return new_key()


def write_config(folder, platform, pem: bytes, **extra) -> str:
    (folder / "tool.pem").write_bytes(pem)
    (folder / "lti_roster.csv").write_text(ROSTER, encoding="utf-8")
    lines = [f'client_id = "cvkit-tool"', f'token_url = "{platform.token_url}"',
             f'lineitems_url = "{platform.lineitems_url}"', 'private_key = "tool.pem"', 'roster = "lti_roster.csv"',
             'key_id = "k1"', "backoff = 0"] + [f"{k} = {v!r}" if not isinstance(v, str) else f'{k} = "{v}"'
                                                 for k, v in extra.items()]
    path = folder / "lti.toml"
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def scores_of(platform, item_id):
    return {s["userId"]: s for i, s in platform.scores if i == item_id}


def test_push_posts_scores_and_reuses_line_items(tmp_path, key):
    pem, public = key
    waits = []
    with Platform("cvkit-tool", public) as platform:
        # on the platform already: an item of another tool, and ch01's made earlier, matched by its tag only
        platform.add_line_item(label="Quiz 1", scoreMaximum=10, tag="quiz")
        earlier = platform.add_line_item(label="Chapter 1", scoreMaximum=6, tag="ch01_intro")
        platform.refuse_users.add("u-cyd")
        platform.unavailable["u-bob"] = 2  # passing failures: repeated until posted
        config = load_config(write_config(tmp_path, platform, pem))
        report = push(sheet(), config, sleep=waits.append)

        # the token: client credentials, a signed assertion the platform verified, both AGS scopes
        assert len(platform.token_requests) == 1
        assert set(platform.token_requests[0]["scope"].split()) == {SCOPE_LINEITEM, SCOPE_SCORE}
        # line items: ch01's reused (its tag), the others made once each, with resourceId and tag
        assert report.reused == ["ch01_intro"] and report.created == ["ch02_formation", "ch03_empty"]
        made = {i["resourceId"]: i for i in platform.line_items if "resourceId" in i}
        assert made["ch02_formation"] == {"id": made["ch02_formation"]["id"], "scoreMaximum": 8.0,
                                          "label": "Zoë's chapter", "resourceId": "ch02_formation",
                                          "tag": "ch02_formation"}
        # the scores, as the platform received them
        first = scores_of(platform, earlier["id"])
        assert set(first) == {"u-ada", "u-bob", "u-zoe"}  # cyd's is not graded: nothing posted
        ada = first["u-ada"]
        assert (ada["scoreGiven"], ada["scoreMaximum"], ada["activityProgress"], ada["gradingProgress"]) == \
            (6.0, 6.0, "Completed", "FullyGraded")
        assert ada["timestamp"].endswith("+00:00") and "T" in ada["timestamp"]
        assert first["u-bob"]["scoreGiven"] == pytest.approx(2 + 2 / 3)  # after the late penalty
        assert "late penalty of 1 point" in first["u-bob"]["comment"]
        second = scores_of(platform, made["ch02_formation"]["id"])
        bob = second["u-bob"]  # written answers to mark: PendingManual, no score (never 0)
        assert bob["gradingProgress"] == "PendingManual" and "scoreGiven" not in bob
        assert bob["activityProgress"] == "Submitted"
        assert second["u-zoe"]["scoreGiven"] == 8.0 and "u-cyd" not in second
        assert scores_of(platform, made["ch03_empty"]["id"]) == {}  # nobody handed it in
        # per student: the refused one reported, the others posted; the 503s repeated
        outcome = {(o.student, o.assignment): o for o in report.outcomes}
        assert outcome[("cyd", "ch02_formation")].status == "failed"
        assert "422" in outcome[("cyd", "ch02_formation")].detail and "not enrolled" in outcome[("cyd", "ch02_formation")].detail
        assert [o for o in report.failed] == [outcome[("cyd", "ch02_formation")]]
        assert outcome[("bob", "ch01_intro")].status == "posted" and outcome[("bob", "ch02_formation")].status == "pending"
        assert report.retried == 2 and len(waits) == 2
        assert outcome[("cyd", "ch01_intro")].status == "skipped" and "not graded" in outcome[("cyd", "ch01_intro")].detail
        assert outcome[("=evil", "ch01_intro")].detail == "no lti_user_id in the roster lti_roster.csv"
        assert any("nina is in the LTI roster but not in the course" in line for line in report.lines)
        # the media types of AGS on every request
        for request in platform.requests:
            if request["method"] == "GET":
                assert request["accept"] == CONTAINER
            elif request["path"].endswith("/scores"):
                assert request["content_type"] == SCORE
            elif request["path"].endswith("/lineitems"):
                assert request["content_type"] == LINEITEM and request["accept"] == LINEITEM

        # a second push: no new line item, the scores posted again (the platform keeps the latest)
        items = len(platform.line_items)
        posted = len(platform.scores)
        again = push(sheet(), config, sleep=waits.append)
        assert len(platform.line_items) == items
        assert again.created == [] and again.reused == ["ch01_intro", "ch02_formation", "ch03_empty"]
        assert len(platform.scores) == 2 * posted
        # the second push read 4 line items, 2 a page: it followed the Link rel="next"
        assert [r["path"] for r in platform.requests if r["method"] == "GET"][-2:] == \
            ["/courses/7/lineitems", "/courses/7/lineitems?page=1"]


def test_the_platform_checks_the_signature(tmp_path, key):
    pem, _ = key
    _, other_public = new_key()
    with Platform("cvkit-tool", other_public) as platform:  # registered with another key
        config = load_config(write_config(tmp_path, platform, pem))
        with pytest.raises(RuntimeError, match="refused cvkit's client assertion: HTTP 401.*bad signature"):
            push(sheet(), config, sleep=lambda s: None)
        assert platform.scores == [] and platform.line_items == []


def test_wrong_audience_is_refused(tmp_path, key):
    pem, public = key
    with Platform("cvkit-tool", public) as platform:
        config = load_config(write_config(tmp_path, platform, pem, audience="https://elsewhere.example/token"))
        with pytest.raises(RuntimeError, match="aud"):
            push(sheet(), config, sleep=lambda s: None)


def test_gives_up_after_the_retries(tmp_path, key):
    pem, public = key
    with Platform("cvkit-tool", public) as platform:
        platform.unavailable["u-ada"] = 100
        config = load_config(write_config(tmp_path, platform, pem, retries=2))
        report = push(sheet(), config, sleep=lambda s: None)
        failed = {(o.student, o.assignment): o.detail for o in report.failed}
        assert set(failed) == {("ada", "ch01_intro"), ("ada", "ch02_formation")}
        assert all("503" in d for d in failed.values())
        assert {s["userId"] for _, s in platform.scores} == {"u-bob", "u-cyd", "u-zoe"}


def test_a_lost_answer_makes_no_second_line_item(tmp_path, key):
    pem, public = key
    with Platform("cvkit-tool", public) as platform:
        platform.lose_created = 1  # ch01's line item is made, the answer lost: a retry must not make another
        config = load_config(write_config(tmp_path, platform, pem))
        report = push(sheet(), config, sleep=lambda s: None)
        assert sorted(i["resourceId"] for i in platform.line_items) == ["ch01_intro", "ch02_formation", "ch03_empty"]
        assert report.created == ["ch01_intro", "ch02_formation", "ch03_empty"] and report.retried == 1
        assert {s["userId"] for i, s in platform.scores if i == platform.line_items[0]["id"]} == {"u-ada", "u-bob",
                                                                                                  "u-zoe"}


def test_the_token_goes_to_no_other_host(tmp_path, key):
    pem, public = key
    with Platform("cvkit-tool", public) as platform:
        platform.line_items.append({"id": "https://attacker.example/li/1", "tag": "ch01_intro", "scoreMaximum": 6})
        config = load_config(write_config(tmp_path, platform, pem))
        with pytest.raises(RuntimeError, match="not on the host of lineitems_url"):
            push(sheet(), config, sleep=lambda s: None)
        assert platform.scores == []


def test_config_errors_name_the_key(tmp_path, key):
    pem, _ = key
    (tmp_path / "tool.pem").write_bytes(pem)
    (tmp_path / "r.csv").write_text("student_id,lti_user_id\n")
    path = tmp_path / "c.toml"
    base = 'client_id = "x"\ntoken_url = "https://lms.example/token"\nlineitems_url = "https://lms.example/li"\n'
    path.write_text(base + 'private_key = "tool.pem"\n')
    with pytest.raises(ValueError, match="missing roster"):
        load_config(path)
    path.write_text(base + 'private_key = "tool.pem"\nroster = "r.csv"\nclient_secret = "s"\n')
    with pytest.raises(ValueError, match="unknown key.*client_secret"):
        load_config(path)
    path.write_text(base.replace("https://lms", "http://lms") + 'private_key = "tool.pem"\nroster = "r.csv"\n')
    with pytest.raises(ValueError, match="token_url must be an https:// URL"):
        load_config(path)
    path.write_text(base + 'private_key = "nope.pem"\nroster = "r.csv"\n')
    with pytest.raises(FileNotFoundError, match="private_key = 'nope.pem'"):
        load_config(path)
    path.write_text(base + 'private_key = "tool.pem"\nroster = "r.csv"\nretries = -1\n')
    with pytest.raises(ValueError, match="retries must be a number"):
        load_config(path)
    with pytest.raises(FileNotFoundError, match="--lti"):
        load_config(tmp_path / "missing.toml")
    assert lti.scores_url("https://lms.example/li/5?type=x") == "https://lms.example/li/5/scores?type=x"
