"""Feedback pages and grade exports that are safe to open.

A student controls much of what ends up in a feedback page: the outputs of every cell their
kernel ran (``text/html``, SVG, Markdown, JavaScript, widget views, any MIME type at all,
including cvkit's own report type), the Markdown and raw cells they wrote (raw HTML,
``javascript:`` links, attachments), cell and notebook metadata, and text that nbgrader's
``feedback`` template prints without escaping (``grade_id``). Grade exports carry their
names and ids into a spreadsheet. This module makes both inert.

Feedback (nbgrader ``generate_feedback``, configured in ``autograders/nbgrader_config.py``)
---------------------------------------------------------------------------------------------
- :class:`SanitizeStudentContent` — a feedback preprocessor (after ``GetGrades``, before
  ``HideHiddenTests``). Every output is rebuilt from an allow-list of MIME types:
  ``text/html`` is cleaned with `nh3 <https://nh3.readthedocs.io>`_ (Ammonia), ``text/markdown``
  is rendered and cleaned into ``text/html``, SVG is kept only when it has no script, event
  handler, ``foreignObject``, animation or external reference (and is shown as an ``<img>``,
  where browsers run no script anyway), PNG/JPEG must be base64, and
  ``application/javascript``, widget views and every other type are dropped (with a note
  when nothing else is left). Only the display outputs that carry cvkit's report MIME type in
  a *test cell decided by the trusted grader* (a cell with ``check(...)`` calls, in a notebook
  that :class:`~cvkit.course.nbgrader_plugins.TrustedChecks` marked ``metadata.cvkit.trusted``)
  keep their report HTML: still cleaned, with an allow-list that fits
  :meth:`cvkit.grading.report.Report._repr_html_` (tables, captions, ``<details>``, ``style`` limited
  to a few layout/colour properties, ``<img>`` only with ``data:image/...;base64`` sources and
  their alt text). The same MIME type from an answer cell, or from any other output, gets the
  strict policy. Markdown cells, HTML raw cells and the graders' comments are rendered here and
  replaced by their cleaned HTML, wrapped so that the template's Markdown pass keeps it as
  it is (other raw cells are never shown in HTML and are dropped); attachments are limited to
  PNG/JPEG/GIF (a missing or dropped one shows its alt text); ``grade_id`` is reduced to
  ``[A-Za-z0-9_.-]``; execution counts must be integers; the notebook's widget state is
  dropped. The strict policy keeps text, links (http, https, mailto, relative), tables,
  lists, code, images from ``data:`` or relative URLs; it drops ``style``, ``class`` (except
  syntax-highlighting classes), ``<style>``, ``<script>``, ``<iframe>``, ``<meta>``, forms,
  ``on*`` attributes, remote images; ``id`` gets a ``md-`` prefix so that it cannot clobber the
  page's or MathJax's elements.
- :class:`SafeFeedbackExporter` — the ``HTMLExporter`` of ``generate_feedback``
  (``c.GenerateFeedback.exporter_class``). It cleans the notebook before the configured
  preprocessors (a notebook made invalid on purpose would otherwise stop nbconvert) and
  again after them if the configuration forgot :class:`SanitizeStudentContent`; it cleans
  whatever its templates render through ``markdown2html`` (a second line of defence for
  Markdown cells and comments; a Markdown error shows the source as text instead of failing
  the page); it always embeds SVG as a base64 ``<img>``; it loads MathJax from the page's
  folder (below).
  nbconvert's own ``HTMLExporter.sanitize_html`` stays off: its ``clean_html`` escapes the
  report's ``<section>`` and drops its images, and nbgrader's ``feedback`` template ignores
  it for Markdown cells anyway.

MathJax without network
-----------------------
nbgrader's feedback template loads MathJax 2.7 from a CDN. cvkit uses the MathJax 2.7.9
files of ``jupyter_server_mathjax`` instead: the Jupyter project's own pip package of MathJax
(made for the classic notebook server, a small wheel with no build step), and MathJax 2 like
the page's configuration script (``MathJax.Hub``), so the templates need no other change (a
MathJax 3 package would need a new configuration and offers nothing the pages use). Every
page loads
``mathjax/MathJax.js?config=TeX-AMS-MML_HTMLorMML-full,Safe`` (relative, with MathJax's
``Safe`` extension, so ``\\href{javascript:...}`` and ``\\style`` are inert) and is configured
for the web fonts that package has (STIX-Web, HTML-CSS output). :func:`install_offline_mathjax`
puts a ``mathjax/`` folder next to every page below a feedback root: one copy of the needed
subset (2.8 MB: no SVG output, no accessibility explorer, no translations) in
``<feedback root>/.mathjax-<version>/`` — hidden, so nbgrader's ``*`` globs never take it for a
student — hard-linked into each page folder (copied where links are impossible), so each
``feedback/<student>/<assignment>/`` folder is complete on its own (zip it, mail it) for the
cost of its directory entries. Each copy is built in ``<feedback root>/.mathjax-work/`` and
moved in place with one rename, so parallel feedback workers can install at once.
``autograders/nbgrader_config.py`` runs it after every ``generate_feedback`` through
nbgrader's ``post_convert_hook`` (:func:`mathjax_post_convert_hook`); calling it again is
cheap and harmless. nbgrader's exchange (``release_feedback``) copies only the ``.html``
files: pages fetched that way show formulas as TeX source — they never reach for the network.

Grade exports (CSV injection)
-----------------------------
:func:`csv_safe` turns a cell that a spreadsheet would read as a formula (``=``, ``+``,
``-``, ``@``, tab, carriage return first, as OWASP recommends) into text by prefixing ``'``;
plain numbers, including negative ones, stay numbers. :func:`sanitize_csv_file` rewrites a
CSV file (nbgrader's ``grades.csv``) with every cell passed through it.
"""
from __future__ import annotations

import copy
import csv
import html
import json
import os
import re
import shutil
import tempfile
import uuid
import xml.etree.ElementTree as ElementTree
from functools import lru_cache
from pathlib import Path
from typing import Any, Iterable

from ..grading.runtime.cells import is_code, is_test_cell, nbgrader_metadata
from .files import whole_file

__all__ = [
    "SanitizeStudentContent", "SafeFeedbackExporter", "sanitize_notebook", "sanitize_html", "sanitize_markdown",
    "safe_svg",
    "MATHJAX_URL", "mathjax_files", "install_offline_mathjax", "mathjax_post_convert_hook",
    "csv_safe", "sanitize_csv_file",
]

# ----------------------------------------------------------------------------- HTML policies
ID_PREFIX = "md-"
_DATA_IMAGE = re.compile(r"data:image/(png|jpeg|gif|webp);base64,[A-Za-z0-9+/=\s]*\Z", re.I)
_SCHEME = re.compile(r"[A-Za-z][A-Za-z0-9+.\-]*:")
_DIMENSION = re.compile(r"\d{1,5}(\.\d+)?(px|%)?\Z")
_HEADINGS = ("h1", "h2", "h3", "h4", "h5", "h6")
# elements removed together with their content (never kept as tags)
_DROP_WITH_CONTENT = {"script", "style", "noscript", "iframe", "frame", "frameset", "object", "embed", "applet",
                      "template", "textarea", "select", "option", "title", "xmp", "noembed", "noframes",
                      "plaintext", "svg", "math", "canvas", "audio", "video", "head", "button"}


_LINK_SCHEMES = ("http", "https", "mailto")


def _url(value: str) -> str:
    """A URL as browsers read it: without tabs and newlines, without leading/trailing controls
    and spaces (WHATWG URL parsing), so that ``ht<tab>tps://`` cannot pass for a relative path."""
    return re.sub(r"[\t\n\r]", "", value).strip("".join(map(chr, range(0x21))))


def _relative_url(url: str) -> bool:
    """A URL that stays next to the page: no scheme, not protocol-relative."""
    return not _SCHEME.match(url) and not url.startswith(("//", "\\\\", "/\\", "\\/"))


def _strict_attribute(tag: str, attribute: str, value: str) -> str | None:
    try:
        if attribute == "src":  # images: embedded rasters or files next to the page, never remote
            url = _url(value)
            return url if _DATA_IMAGE.match(url) or _relative_url(url) else None
        if attribute == "href":
            url = _url(value)
            if url.startswith("#"):  # in-page links follow the prefixed ids
                fragment = url[1:]
                return "#" + (fragment if fragment.startswith(ID_PREFIX) else ID_PREFIX + fragment) if fragment else None
            scheme = _SCHEME.match(url)
            if scheme and scheme.group(0)[:-1].lower() not in _LINK_SCHEMES or "script:" in url.lower():
                return None
            return url
        if attribute == "id":  # idempotent, so that cleaning twice keeps links and targets together
            return value if value.startswith(ID_PREFIX) else ID_PREFIX + value
        if attribute in ("width", "height"):
            return value if _DIMENSION.match(value.strip()) else None
        if attribute == "class":  # only the classes of nbconvert's own Markdown/code rendering
            kept = [name for name in value.split() if name in _strict_classes().get(tag, ())]
            return " ".join(kept) or None
        return value
    except Exception:  # never raise inside the sanitiser (it would only be reported, not raised)
        return None


def _report_attribute(tag: str, attribute: str, value: str) -> str | None:
    try:
        if attribute == "src":
            url = _url(value)
            return url if _DATA_IMAGE.match(url) else None
        if attribute in ("width", "height"):
            return value if _DIMENSION.match(value.strip()) else None
        return value
    except Exception:
        return None


@lru_cache(maxsize=1)
def _strict_classes() -> dict[str, frozenset]:
    try:
        from pygments.token import STANDARD_TYPES

        highlighting = frozenset(name for name in STANDARD_TYPES.values() if name)
    except Exception:  # pragma: no cover - pygments comes with nbconvert
        highlighting = frozenset()
    return {"a": frozenset({"anchor-link"}), "div": frozenset({"highlight", "cvkit-md"}), "span": highlighting}


@lru_cache(maxsize=None)
def _cleaner(policy: str):
    import nh3

    if policy == "report":
        tags = {"section", "div", "p", "span", "b", "strong", "i", "em", "code", "pre", "kbd", "samp", "small",
                "sub", "sup", "br", "hr", "table", "caption", "colgroup", "col", "thead", "tbody", "tfoot", "tr",
                "th", "td", "figure", "figcaption", "img", "details", "summary", "ul", "ol", "li", "dl", "dt", "dd",
                "h3", "h4", "h5", "h6"}
        return nh3.Cleaner(
            tags=tags,
            clean_content_tags=_DROP_WITH_CONTENT - tags,
            attributes={"*": {"class", "style", "title", "role", "aria-label", "aria-hidden", "aria-describedby"},
                        "th": {"scope", "colspan", "rowspan"}, "td": {"colspan", "rowspan"},
                        "img": {"src", "alt", "width", "height"}, "details": {"open"}, "ol": {"start"}},
            attribute_filter=_report_attribute,
            url_schemes={"data"},
            filter_style_properties={
                "border", "border-left", "border-right", "border-top", "border-bottom", "border-color",
                "border-collapse", "border-radius", "padding", "padding-left", "padding-right", "padding-top",
                "padding-bottom", "margin", "margin-left", "margin-right", "margin-top", "margin-bottom",
                "font-family", "font-weight", "font-size", "font-style", "color", "background",
                "background-color", "white-space", "text-align", "vertical-align", "image-rendering", "width",
                "height", "max-width", "max-height", "display", "line-height"},
            link_rel=None,
        )
    tags = set(nh3.ALLOWED_TAGS) - {"map", "area"}
    attributes = {"*": {"title", "lang", "dir"}, "a": {"href", "hreflang"}, "img": {"src", "alt", "width", "height"},
                  "td": {"colspan", "rowspan", "align"}, "th": {"colspan", "rowspan", "align", "scope"},
                  "ol": {"start"}, "abbr": {"title"}, "details": {"open"}}
    for heading in _HEADINGS:
        attributes[heading] = {"id"}
    for tag in _strict_classes():
        attributes.setdefault(tag, set()).add("class")
    return nh3.Cleaner(
        tags=tags,
        clean_content_tags=_DROP_WITH_CONTENT - tags,
        attributes=attributes,
        attribute_filter=_strict_attribute,
        url_schemes={*_LINK_SCHEMES, "data"},  # data: only for raster images (see the filter)
        link_rel="noopener noreferrer nofollow",
    )


def sanitize_html(fragment: str, *, trusted_report: bool = False) -> str:
    """An HTML fragment without scripts, event handlers, frames, styles or remote loads.

    ``trusted_report=True`` selects the allow-list of cvkit's grading reports (inline
    ``style`` with layout/colour properties, classes, ``data:`` images); use it only for HTML
    that cvkit's trusted grader produced. Everything else gets the strict policy."""
    if not isinstance(fragment, str):
        fragment = "".join(fragment) if isinstance(fragment, list) else str(fragment)
    return _cleaner("report" if trusted_report else "strict").clean(fragment)


class _Attachments(dict):
    """Attachments for nbconvert's renderer: a name that is missing (or was dropped as unsafe)
    becomes a broken image that shows its alt text, instead of an error for the whole cell."""

    def __contains__(self, name) -> bool:
        return True

    def __missing__(self, name) -> dict:
        return {"image/png": ""}


def _render_markdown(source: str, attachments: dict | None = None) -> str:
    from nbconvert.filters.markdown_mistune import IPythonRenderer, MarkdownWithMath

    renderer = IPythonRenderer(escape=False, attachments=_Attachments(attachments or {}), anchor_link_text="¶")
    return MarkdownWithMath(renderer=renderer).render(source)


def sanitize_markdown(source: str, attachments: dict | None = None) -> str:
    """Markdown (with math, as nbconvert renders it) to cleaned HTML. Math stays as TeX text
    for MathJax. A source that cannot be rendered (say, a missing attachment) becomes text."""
    try:
        rendered = _render_markdown(source, _safe_attachments(attachments))
    except Exception:
        rendered = f"<pre>{html.escape(source)}</pre>"
    return sanitize_html(rendered)


_BLOCK = '<div class="cvkit-md">'


def _html_block(fragment: str) -> str:
    """Cleaned HTML that a Markdown renderer passes through unchanged: one ``<div>`` on one
    line (an HTML block ends at the first blank line; newlines become character references,
    which mean the same in HTML)."""
    line = fragment.replace("\r", "").replace("\n", "&#10;")
    return line if line.startswith(_BLOCK) else _BLOCK + line + "</div>"


def _markdown_block(source: str, attachments=None) -> str:
    """Markdown source as a cleaned HTML block (a block made here before is only cleaned again).
    A cell without attachments is made once per process (most of a class's Markdown cells are
    the release's own): the same source gives the same block."""
    if not attachments and len(source) <= 20_000:
        return _plain_markdown_block(source)
    cleaned = sanitize_html(source) if source.startswith(_BLOCK) else sanitize_markdown(source, attachments)
    return _html_block(cleaned) if cleaned.strip() else ""


@lru_cache(maxsize=4096)
def _plain_markdown_block(source: str) -> str:
    cleaned = sanitize_html(source) if source.startswith(_BLOCK) else sanitize_markdown(source, None)
    return _html_block(cleaned) if cleaned.strip() else ""


# ----------------------------------------------------------------------------- SVG
_SVG_FORBIDDEN = {"script", "foreignobject", "iframe", "object", "embed", "audio", "video", "animate", "set",
                  "animatemotion", "animatetransform", "animatecolor", "handler", "listener", "discard"}


def safe_svg(svg: str) -> str | None:
    """``svg`` itself when it is inert (no script, event handler, foreignObject, animation,
    external reference or XML entity), else ``None``. (It is shown as an ``<img>`` anyway.)"""
    if not isinstance(svg, str):
        svg = "".join(svg) if isinstance(svg, list) else str(svg)
    lowered = svg.lower()
    if "<!doctype" in lowered or "<!entity" in lowered or len(svg) > 20_000_000:
        return None
    try:
        root = ElementTree.fromstring(svg)
    except Exception:
        return None
    for element in root.iter():
        if not isinstance(element.tag, str):
            return None
        if element.tag.rsplit("}", 1)[-1].lower() in _SVG_FORBIDDEN:
            return None
        for name, value in element.attrib.items():
            local = name.rsplit("}", 1)[-1].lower()
            if local.startswith("on"):
                return None
            if local in ("href", "src") or "javascript:" in value.lower().replace(" ", ""):
                text = value.strip()
                if not (text.startswith("#") or _DATA_IMAGE.match(text)):
                    return None
            if "url(" in value.lower() and not re.fullmatch(r"[^()]*url\(\s*['\"]?#[^)]*\)[^()]*", value, re.S):
                return None
        if element.tag.rsplit("}", 1)[-1].lower() == "style" and element.text:
            css = element.text.lower()
            if "@import" in css or re.search(r"url\(\s*['\"]?(?!#)", css):
                return None
    return svg


# ----------------------------------------------------------------------------- notebook content
_TEXT_TYPES = ("text/plain", "text/latex")
_IMAGE_TYPES = ("image/png", "image/jpeg")
_ATTACHMENT_TYPES = ("image/png", "image/jpeg", "image/gif")
_BASE64 = re.compile(r"[A-Za-z0-9+/=\s]*\Z")
_GRADE_ID = re.compile(r"[^A-Za-z0-9_.\-]")


def _text(value: Any) -> str:
    if isinstance(value, str):
        return value
    if isinstance(value, list):
        return "".join(str(v) for v in value)
    return "" if value is None else str(value)


def _safe_attachments(attachments) -> dict:
    safe = {}
    for name, bundle in (attachments or {}).items():
        if not isinstance(bundle, dict):
            continue
        kept = {mime: _text(data) for mime, data in bundle.items()
                if mime in _ATTACHMENT_TYPES and _BASE64.match(_text(data))}
        if kept:
            safe[str(name)] = kept
    return safe


def _report_mime() -> str:
    from ..grading.report import MIME_TYPE

    return MIME_TYPE


def _trusted_test_cell(cell, notebook_trusted: bool) -> bool:
    """A test cell whose outputs cvkit's trusted grader replaced: a code cell with nbgrader
    ``grade`` and not ``solution`` and ``check(...)`` calls in its (instructor's) source, in a
    notebook that went through :class:`~cvkit.course.nbgrader_plugins.TrustedChecks`."""
    if not notebook_trusted or not is_code(cell) or not is_test_cell(cell):
        return False
    from .trusted import check_calls

    return bool(check_calls(_text(cell.get("source", "")), str(nbgrader_metadata(cell).get("grade_id", ""))))


def _image_metadata(metadata: dict, mime: str) -> dict:
    source = metadata.get(mime, {}) if isinstance(metadata, dict) else {}
    kept = {}
    if isinstance(source, dict):
        for key in ("width", "height"):
            if isinstance(source.get(key), (int, float)) and not isinstance(source.get(key), bool):
                kept[key] = source[key]
        if isinstance(source.get("unconfined"), bool):
            kept["unconfined"] = source["unconfined"]
        if isinstance(source.get("alt"), str):
            kept["alt"] = source["alt"]
    return kept


def _clean_bundle(data: dict, metadata: dict, *, trusted: bool) -> tuple[dict, dict]:
    """The MIME bundle of one display/execute output, rebuilt from the allow-list."""
    report_mime = _report_mime()
    kept, meta, dropped = {}, {}, []
    for mime, value in (data or {}).items():
        if mime in _TEXT_TYPES:
            kept[mime] = _text(value)
        elif mime == "text/html":
            cleaned = sanitize_html(_text(value), trusted_report=trusted)
            if cleaned.strip():
                kept[mime] = cleaned
        elif mime == "text/markdown":
            continue  # rendered below, unless there is HTML already
        elif mime in _IMAGE_TYPES:
            text = _text(value)
            if _BASE64.match(text):
                kept[mime] = text
                image_meta = _image_metadata(metadata, mime)
                if image_meta:
                    meta[mime] = image_meta
            else:
                dropped.append(mime)
        elif mime == "image/svg+xml":
            svg = safe_svg(value)
            if svg is not None:
                kept[mime] = svg
            else:
                dropped.append(mime)
        elif mime == report_mime and trusted:
            kept[mime] = value
        else:
            dropped.append(mime)
    if "text/markdown" in (data or {}) and "text/html" not in kept:
        cleaned = sanitize_markdown(_text(data["text/markdown"]))
        if cleaned.strip():
            kept["text/html"] = cleaned
    if not any(mime in kept for mime in ("text/plain", "text/html", "text/latex", *_IMAGE_TYPES, "image/svg+xml")):
        shown = ", ".join(sorted(set(dropped))) or "empty output"
        kept["text/plain"] = f"[not shown in the feedback: {shown}]"
    return kept, meta


def _clean_output(output, *, trusted_cell: bool):
    from nbformat.v4 import new_output

    if not isinstance(output, dict):
        return None
    kind = output.get("output_type")
    if kind == "stream":
        name = output.get("name") if output.get("name") in ("stdout", "stderr") else "stdout"
        return new_output("stream", name=name, text=_text(output.get("text", "")))
    if kind == "error":
        traceback = output.get("traceback", [])
        traceback = [_text(line) for line in traceback] if isinstance(traceback, list) else [_text(traceback)]
        return new_output("error", ename=_text(output.get("ename", "")), evalue=_text(output.get("evalue", "")),
                          traceback=traceback)
    if kind in ("display_data", "execute_result"):
        data = output.get("data", {}) if isinstance(output.get("data"), dict) else {}
        trusted = trusted_cell and kind == "display_data" and _report_mime() in data
        bundle, metadata = _clean_bundle(data, output.get("metadata", {}), trusted=trusted)
        if kind == "execute_result":
            count = output.get("execution_count")
            return new_output("execute_result", data=bundle, metadata=metadata,
                              execution_count=count if isinstance(count, int) and not isinstance(count, bool) else None)
        return new_output("display_data", data=bundle, metadata=metadata)
    return None


def sanitize_notebook(nb, resources: dict | None = None):
    """Make every student-controlled part of ``nb`` (a NotebookNode, changed in place) inert
    for an HTML page; see the module docstring. Returns ``nb``."""
    from nbformat import NotebookNode

    notebook_trusted = (nb.get("metadata", {}).get("cvkit", {}) or {}).get("trusted") is True
    cells = []
    for cell in nb.cells:
        if not isinstance(cell, dict):
            continue
        kind = cell.get("cell_type")
        if kind not in ("code", "markdown", "raw"):
            continue
        if not isinstance(cell.get("metadata"), dict):
            cell["metadata"] = NotebookNode()
        metadata = cell["metadata"]
        metadata.pop("magics_language", None)
        grading = metadata.get("nbgrader")
        if isinstance(grading, dict):
            if "grade_id" in grading:
                grading["grade_id"] = _GRADE_ID.sub("_", _text(grading["grade_id"]))
            if grading.get("comment"):
                grading["comment"] = _markdown_block(_text(grading["comment"]))
        elif grading is not None:
            metadata.pop("nbgrader")
        tags = metadata.get("tags")
        if tags is not None and not (isinstance(tags, list) and all(isinstance(t, str) for t in tags)):
            metadata.pop("tags")
        if kind == "code":
            count = cell.get("execution_count")
            if not (isinstance(count, int) and not isinstance(count, bool)):
                cell["execution_count"] = None
            trusted_cell = _trusted_test_cell(cell, notebook_trusted)
            raw = cell.get("outputs")
            outputs = [_clean_output(o, trusted_cell=trusted_cell) for o in (raw if isinstance(raw, list) else [])]
            cell["outputs"] = [o for o in outputs if o is not None]
        elif kind == "markdown":
            cell["source"] = _markdown_block(_text(cell.get("source", "")), cell.get("attachments"))
            cell.pop("attachments", None)
        else:  # raw cells: HTML ones become cleaned HTML blocks, the others are not shown in HTML anyway
            mimetype = _text(metadata.get("raw_mimetype", metadata.get("format", ""))).lower()
            if mimetype not in ("", "text/html"):
                continue
            cleaned = sanitize_html(_text(cell.get("source", "")))
            cell = NotebookNode(cell_type="markdown", metadata=NotebookNode(), source=_html_block(cleaned),
                                **({"id": cell["id"]} if "id" in cell else {}))
        cells.append(cell)
    nb.cells = cells
    nb.metadata.pop("widgets", None)
    if "title" in nb.metadata:  # nbconvert's templates escape it; nbgrader's does not show it
        nb.metadata["title"] = re.sub(r"[<>]", "", _text(nb.metadata["title"]))
    if resources is not None:
        info = resources.get("nbgrader")
        if isinstance(info, dict) and "notebook" in info:
            info["notebook"] = html.escape(_text(info["notebook"]))
        resources["cvkit_sanitized"] = True
    return nb


def _preprocessor_class():
    from nbconvert.preprocessors import Preprocessor
    from traitlets import Bool

    class _SanitizeStudentContent(Preprocessor):
        """Feedback preprocessor: strip everything executable from student-controlled content,
        keep cvkit's trusted reports. Put it after ``GetGrades`` and before ``HideHiddenTests``
        (so that it still sees the trusted grader's hidden checks); see the module docstring."""

        enabled = Bool(True).tag(config=True)

        def preprocess(self, nb, resources):
            if resources is None:
                resources = {}
            return sanitize_notebook(nb, resources), resources

        def preprocess_cell(self, cell, resources, index):  # pragma: no cover - whole-notebook preprocessor
            return cell, resources

    return _SanitizeStudentContent


# ----------------------------------------------------------------------------- MathJax
MATHJAX_DIR = "mathjax"
MATHJAX_CONFIG = "TeX-AMS-MML_HTMLorMML-full,Safe"
MATHJAX_URL = f"{MATHJAX_DIR}/MathJax.js?config={MATHJAX_CONFIG}"
_MATHJAX_STAMP = ".cvkit-mathjax"
# not shipped next to the pages: SVG output (HTML-CSS is used), the accessibility explorer,
# translations (English is built in)
_MATHJAX_SKIP = ("extensions/a11y/", "jax/output/SVG/", "localization/")

_MATHJAX_MACRO = r"""
{%- macro mathjax(url="__URL__") -%}
    <!-- MathJax, from the folder of this page (no network) -->
    <script type="text/javascript">
    window.MathJax = {
        TeX: {equationNumbers: {autoNumber: "AMS", useLabelIds: true}},
        tex2jax: {inlineMath: [['$', '$'], ["\\(", "\\)"]], displayMath: [['$$', '$$'], ["\\[", "\\]"]],
                  processEscapes: true, processEnvironments: true},
        "HTML-CSS": {availableFonts: [], preferredFont: null, webFont: "STIX-Web", imageFont: null,
                     linebreaks: {automatic: true}},
        MathMenu: {showRenderer: false, showLocale: false, showFontMenu: false},
        displayAlign: "center",
        messageStyle: "none"
    };
    </script>
    <script type="text/javascript" src="{{ url | e }}"></script>
{%- endmacro %}
""".replace("__URL__", MATHJAX_URL)


def _mathjax_source() -> Path:
    import jupyter_server_mathjax

    return Path(jupyter_server_mathjax.__file__).resolve().parent / "static"


@lru_cache(maxsize=1)
def _mathjax_manifest() -> tuple[str, tuple[str, ...]]:
    """(version, relative paths) of the MathJax subset shipped next to the pages."""
    root = _mathjax_source()
    text = (root / "MathJax.js").read_text(encoding="utf-8", errors="replace")
    found = re.search(r'MathJax\.version\s*=\s*"([^"]+)"', text)
    version = found.group(1) if found else "unknown"
    files = []
    for path in sorted(root.rglob("*")):
        if path.is_file():
            relative = path.relative_to(root).as_posix()
            if not relative.startswith(_MATHJAX_SKIP):
                files.append(relative)
    return version, tuple(files)


def mathjax_files() -> list[str]:
    """The files (relative to the ``mathjax/`` folder) that :func:`install_offline_mathjax` ships."""
    return list(_mathjax_manifest()[1])


def _stamp() -> str:
    version, files = _mathjax_manifest()
    return f"MathJax {version} from jupyter_server_mathjax, {len(files)} files\n"


def _fresh(folder: Path) -> bool:
    try:
        return (folder / _MATHJAX_STAMP).read_text() == _stamp()
    except OSError:
        return False


def _replace_folder(target: Path, fill, scratch: Path) -> None:
    """Build ``target`` in a private folder below ``scratch`` and move it in place with one
    rename: a page folder never shows a half-written ``mathjax/`` (nbgrader may be walking it
    to set permissions), and when several processes install at once the first complete copy
    stays and the others are thrown away."""
    scratch.mkdir(parents=True, exist_ok=True)
    work = Path(tempfile.mkdtemp(prefix="build-", dir=scratch))
    try:
        fill(work)
        (work / _MATHJAX_STAMP).write_text(_stamp())
        work.chmod(0o755)
        if target.exists() and not _fresh(target):  # an older or broken copy: out of the way first
            try:
                target.rename(scratch / f"old-{uuid.uuid4().hex}")
            except OSError:
                pass
        try:
            work.rename(target)
        except OSError:
            if not _fresh(target):
                raise
    finally:
        for leftover in [work, *scratch.glob("old-*")]:
            shutil.rmtree(leftover, ignore_errors=True)


def _scratch(root: Path) -> Path:
    return root / ".mathjax-work"


def _master(root: Path) -> Path:
    version, files = _mathjax_manifest()
    master = root / f".mathjax-{version}"
    if not _fresh(master):
        source = _mathjax_source()

        def fill(work: Path) -> None:
            for relative in files:
                dest = work / relative
                dest.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(source / relative, dest)
                dest.chmod(0o644)

        _replace_folder(master, fill, _scratch(root))
    return master


def _link_tree(master: Path, target: Path, scratch: Path) -> None:
    def fill(work: Path) -> None:
        for relative in mathjax_files():
            dest = work / relative
            dest.parent.mkdir(parents=True, exist_ok=True)
            try:
                os.link(master / relative, dest)
            except OSError:
                shutil.copyfile(master / relative, dest)

    _replace_folder(target, fill, scratch)


def install_offline_mathjax(feedback_root, folders: Iterable | None = None) -> list[Path]:
    """Put MathJax (``mathjax/``) next to every feedback page below ``feedback_root``.

    ``folders`` limits the work to these page folders (default: every folder below
    ``feedback_root`` that holds an ``.html`` file; hidden folders are skipped). Folders that
    already have this MathJax are left alone, so calling it again is cheap (with thousands of
    page folders, pass the new ones as ``folders``). A folder that disappears meanwhile (its
    feedback being generated again) is skipped. Returns the page folders that have MathJax.
    The files are hard links to one copy in ``feedback_root/.mathjax-<version>/`` (copies on
    file systems without links); all work happens in ``feedback_root/.mathjax-work/``."""
    root = Path(feedback_root)
    if folders is None:
        folders = []
        for here, subfolders, names in os.walk(root):  # never into the MathJax copies themselves
            subfolders[:] = sorted(d for d in subfolders if d != MATHJAX_DIR and not d.startswith("."))
            if any(name.endswith(".html") for name in names):
                folders.append(Path(here))
    folders = [Path(f) for f in folders if Path(f).is_dir()]
    if not folders:
        return []
    master = _master(root)
    done = []
    for folder in folders:
        try:
            if not _fresh(folder / MATHJAX_DIR):
                _link_tree(master, folder / MATHJAX_DIR, _scratch(root))
        except OSError:
            if folder.is_dir():
                raise
            continue
        done.append(folder)
    return done


def mathjax_post_convert_hook(feedback_root):
    """A ``GenerateFeedback.post_convert_hook`` that runs :func:`install_offline_mathjax` on
    the feedback folders nbgrader just wrote (``feedback_root/<student>/<assignment>``)."""
    root = Path(feedback_root)

    def hook(assignment: str = "*", student: str = "*", notebooks=None, **_):
        pattern = f"{student or '*'}/{assignment or '*'}"
        folders = [p for p in root.glob(pattern) if p.is_dir() and any(p.glob("*.html"))]
        install_offline_mathjax(root, folders if folders else None)

    return hook


# ----------------------------------------------------------------------------- exporter
def _without_mark_schemes(nb):
    """The notebook without the mark schemes of its open tasks: nbgrader's autograde restores
    locked task cells from the instructor's version, mark scheme included, and the feedback
    page must not show it. Done before sanitizing, which drops the HTML comments that often
    delimit the mark scheme (``<!-- BEGIN MARK SCHEME -->``)."""
    from nbgrader.preprocessors import ClearMarkScheme

    return ClearMarkScheme(enforce_metadata=False).preprocess(nb, {})[0]


_IMAGE_WITHOUT_ALT = re.compile(r"<img(?![^>]*\salt=)(?=[\s>/])", re.IGNORECASE)
_NO_ALT_TEXT = "No description has been provided for this image"


def _with_alt_texts(page: str) -> str:
    """Every ``<img>`` of the page with an ``alt`` attribute (as nbconvert's HTMLExporter adds)."""
    return _IMAGE_WITHOUT_ALT.sub(f'<img alt="{_NO_ALT_TEXT}"', page)


_EXERCISE_HEADING = re.compile(r"^#{1,6}\s+(Exercise\s+[0-9][0-9.]*[a-z]?)\b", re.M)
_TEST_KINDS = {"visible": "visible test", "hidden": "hidden tests", "test": "test"}


def contents_names(nb) -> dict[str, str]:
    """The name of each test cell for the feedback page's list of contents, by its grade id
    (as :func:`sanitize_notebook` leaves it): the exercise it tests and which test it is, e.g.
    ``"Exercise 4.4 magnitude: visible test"`` for ``magnitude_visible`` under the heading
    "### Exercise 4.4 — …" (nbgrader's template says "Test cell" for every one of them)."""
    names: dict[str, str] = {}
    exercise = ""
    for cell in nb.get("cells", []) if isinstance(nb, dict) else []:
        if not isinstance(cell, dict):
            continue
        if cell.get("cell_type") == "markdown":
            found = _EXERCISE_HEADING.search(_text(cell.get("source", "")))
            if found:
                exercise = " ".join(found.group(1).split())
            continue
        meta = (cell.get("metadata") or {}).get("nbgrader") if isinstance(cell.get("metadata"), dict) else None
        if not isinstance(meta, dict) or not meta.get("grade") or meta.get("solution") or "grade_id" not in meta:
            continue
        grade_id = _GRADE_ID.sub("_", _text(meta["grade_id"]))
        stem, _, kind = grade_id.rpartition("_")
        if kind not in _TEST_KINDS or not stem:
            stem, kind = grade_id, "test"
        names[grade_id] = f"{exercise} {stem}: {_TEST_KINDS[kind]}".strip()[:120]
    return names


def _named_contents(page: str, names: dict[str, str]) -> str:
    """The page's list of contents with each test cell's name instead of "Test cell"."""
    def name(match: re.Match) -> str:
        grade_id = match.group(1)
        label = names.get(grade_id)
        return match.group(0) if label is None else f'<a href="#{grade_id}">{html.escape(label)}</a>'

    return re.sub(r'<a href="#([A-Za-z0-9_.\-]+)">Test cell</a>', name, page)


def _waiting_marks(page: str, waiting: dict[str, float]) -> str:
    """nbgrader's page with "waiting for your instructor" where a cell waits for a hand mark
    (``waiting``: grade id → points): in the list of contents, in the cell's heading, and after the
    notebook's score (which counts those points as 0 until they are marked)."""
    if not waiting:
        return page

    def points(value: float) -> str:
        return f"{value:g} point{'s' * (value != 1)}"

    for grade_id, value in waiting.items():
        gid = re.escape(_GRADE_ID.sub("_", grade_id))
        page = re.sub(rf'(<a href="#{gid}">[^<]*</a>) \(Score: [^)]*\)',
                      lambda m: f"{m.group(1)} (waiting for your instructor: {points(value)})", page, count=1)
        page = re.sub(rf'(<a name="(?:comment-)?{gid}"></a>\s*<div class="panel-heading">(?:(?!</div>).)*?<span class="pull-right">\s*)'
                      r'Score: [^<]*?(<a href="#top">)',
                      lambda m: f"{m.group(1)}Waiting for your instructor ({points(value)}) {m.group(2)}", page,
                      count=1, flags=re.S)
    total = sum(waiting.values())
    return re.sub(r'(<h4>[^<]*\(Score: [^)]*\))(</h4>)',
                  lambda m: f"{m.group(1)} — {points(total)} still waiting for your instructor{m.group(2)}", page,
                  count=1)


#: highlighted code of this process, by (source, language, metadata, formatter options): most
#: cells of a class's pages are the release's own, highlighted once per worker, not per page
_HIGHLIGHTED: dict[tuple[str, ...], str] = {}
_HIGHLIGHT_KEEP = 4096           # entries kept (then the memo starts again)
_HIGHLIGHT_LARGEST = 20_000      # characters of a source worth keeping


class _Highlighted:
    """A highlight filter (nbconvert's ``Highlight2HTML``) that keeps what it made, for the
    next page: the same arguments give the same HTML, so the pages are unchanged."""

    def __init__(self, highlight: Any) -> None:
        self.highlight = highlight

    def __call__(self, source: str, language: str | None = None, metadata: Any = None) -> str:
        if len(source) > _HIGHLIGHT_LARGEST:
            return self.highlight(source, language, metadata)
        key = (source, str(language or self.highlight.pygments_lexer),
               json.dumps(metadata, sort_keys=True, default=str) if metadata else "",
               repr(sorted(self.highlight.extra_formatter_options.items())))
        found = _HIGHLIGHTED.get(key)
        if found is None:
            found = self.highlight(source, language, metadata)
            if len(_HIGHLIGHTED) >= _HIGHLIGHT_KEEP:
                _HIGHLIGHTED.clear()
            _HIGHLIGHTED[key] = found
        return found


def _compiled_templates() -> Any:
    """One jinja2 bytecode cache for the process: nbgrader makes a new exporter, hence a new
    template environment, for every feedback page, and compiling nbconvert's templates again
    took about half a second a page. Templates are checked against their source (jinja2 keeps a
    checksum), so a changed template is compiled again."""
    from jinja2 import BytecodeCache

    class _InMemory(BytecodeCache):
        def __init__(self) -> None:
            self.codes: dict[str, bytes] = {}

        def load_bytecode(self, bucket: Any) -> None:
            code = self.codes.get(bucket.key)
            if code is not None:
                bucket.bytecode_from_string(code)

        def dump_bytecode(self, bucket: Any) -> None:
            self.codes[bucket.key] = bucket.bytecode_to_string()

    global _COMPILED
    if _COMPILED is None:
        _COMPILED = _InMemory()
    return _COMPILED


_COMPILED: Any = None


def _exporter_class():
    from jinja2 import DictLoader
    from nbconvert.exporters import HTMLExporter, TemplateExporter
    from nbconvert.filters.highlight import Highlight2HTML
    from nbconvert.filters.widgetsdatatypefilter import WidgetsDataTypeFilter
    from traitlets import default

    try:
        from jinja2 import pass_context
    except ImportError:  # pragma: no cover - jinja2 < 3
        from jinja2 import contextfilter as pass_context

    class _SafeFeedbackExporter(HTMLExporter):
        """nbgrader's feedback exporter, safe to open offline; see the module docstring."""

        @default("extra_loaders")
        def _extra_loaders_default(self):
            return [DictLoader({"mathjax.html.j2": _MATHJAX_MACRO})]

        @default("mathjax_url")
        def _mathjax_url_default(self):
            return MATHJAX_URL

        @default("optimistic_validation")
        def _optimistic_validation_default(self):
            return True

        @pass_context
        def markdown2html(self, context, source):
            try:
                rendered = HTMLExporter.markdown2html(self, context, source)
            except Exception:  # e.g. a missing attachment: show the text, keep the page
                rendered = f"<pre>{html.escape(_text(source))}</pre>"
            return sanitize_html(rendered)

        def from_notebook_node(self, nb, resources=None, **kw):
            # HTMLExporter's own version renders the template, then parses the whole page
            # with BeautifulSoup to add alt texts and JupyterLab-only tabindex attributes:
            # about 60 % of a feedback page's time (2 s of 3.5 s for Chapter 7), for a classic
            # template where the tabindex selectors match nothing. The same filters are
            # registered here; the alt texts are added by _with_alt_texts.
            langinfo = nb.metadata.get("language_info", {})
            lexer = langinfo.get("pygments_lexer", langinfo.get("name", None))
            self.register_filter("highlight_code", self.filters.get(
                "highlight_code", _Highlighted(Highlight2HTML(pygments_lexer=lexer, parent=self))))
            resources = self._init_resources(resources)
            self.register_filter("filter_data_type", WidgetsDataTypeFilter(
                notebook_metadata=self._nb_metadata, parent=self, resources=resources))
            names = contents_names(nb)
            page, resources = TemplateExporter.from_notebook_node(self, nb, resources, **kw)
            page = _waiting_marks(_named_contents(_with_alt_texts(page), names), resources.get("cvkit_waiting") or {})
            return page, resources

        def _create_environment(self):
            environment = super()._create_environment()
            environment.bytecode_cache = _compiled_templates()
            return environment

        def _init_resources(self, resources):
            resources = super()._init_resources(resources)
            resources["should_not_encode_svg"] = False  # SVG only ever as <img>: no script runs there
            return resources

        def _preprocess(self, nb, resources):
            # cleaned once: by SanitizeStudentContent where the configuration has it (nbconvert
            # validates the notebook after the last step only, optimistic_validation, so a
            # notebook a student made invalid reaches it), else here, after the steps
            nb = _without_mark_schemes(copy.deepcopy(nb))
            if not (self.optimistic_validation and _configured_sanitizer(self)):
                nb = sanitize_notebook(nb)
            nb, resources = super()._preprocess(nb, resources)
            if not resources.get("cvkit_sanitized"):
                sanitize_notebook(nb, resources)
            return nb, resources

    return _SafeFeedbackExporter


def _configured_sanitizer(exporter: Any) -> bool:
    """Whether ``exporter``'s steps include :class:`SanitizeStudentContent` (by class or name)."""
    return any(type(step).__name__ == "SanitizeStudentContent" for step in exporter._preprocessors)


_LAZY = {"SanitizeStudentContent": _preprocessor_class, "SafeFeedbackExporter": _exporter_class}


def __getattr__(name):  # the nbconvert classes are built on first use (nbconvert is slow to import)
    if name in _LAZY:
        cls = _LAZY[name]()
        cls.__name__ = cls.__qualname__ = name
        cls.__module__ = __name__
        globals()[name] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ----------------------------------------------------------------------------- CSV
_FORMULA_START = ("=", "+", "-", "@", "\t", "\r")
_PLAIN_NUMBER = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?\Z")


def csv_safe(value) -> str:
    """``value`` as a CSV cell that no spreadsheet evaluates: text starting with ``=``, ``+``,
    ``-``, ``@``, a tab or a carriage return gets a leading ``'`` (OWASP's advice); numbers
    (``-1.5``, ``"-1.5"``, ``"+3e-2"``) stay as they are, and so does ``None`` → ``""``.

    >>> [csv_safe(v) for v in (-1.5, "-1.5", "=1+1", "@SUM(A1)", "alice", None)]
    ['-1.5', '-1.5', "'=1+1", "'@SUM(A1)", 'alice', '']
    """
    if value is None:
        return ""
    if isinstance(value, bool):
        return str(value)
    try:
        import numbers

        if isinstance(value, numbers.Number):
            return str(value)
    except Exception:  # pragma: no cover
        pass
    text = value if isinstance(value, str) else str(value)
    if text.startswith(_FORMULA_START) and not _PLAIN_NUMBER.match(text):
        return "'" + text
    return text


def sanitize_csv_file(path) -> Path:
    """Rewrite the CSV file ``path`` in place with every cell passed through :func:`csv_safe`
    (properly quoted; whole or not at all: :func:`~cvkit.course.files.whole_file`)."""
    path = Path(path)
    with path.open(newline="", encoding="utf-8", errors="surrogateescape") as handle:
        rows = list(csv.reader(handle))
    with whole_file(path, mode=path.stat().st_mode & 0o777, newline="", errors="surrogateescape") as handle:
        writer = csv.writer(handle, lineterminator="\n")  # as nbgrader writes it
        for row in rows:
            writer.writerow([csv_safe(cell) for cell in row])
    return path
