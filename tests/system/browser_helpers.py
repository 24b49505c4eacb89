"""What the browser tests share: a page opened offline in Chromium, and the WCAG contrast of a
rendered element with its background."""
from __future__ import annotations

import contextlib
import shutil
from pathlib import Path

import pytest

#: the contrast ratio (WCAG 2) of an element's text colour with the first opaque background
#: around it (white when none), computed in the page
CONTRAST = """(element) => {
        const rgb = (text) => (text.match(/[\\d.]+/g) || []).slice(0, 4).map(Number);
        const luminance = ([r, g, b]) => {
            const f = (c) => { c /= 255; return c <= 0.03928 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4); };
            return 0.2126 * f(r) + 0.7152 * f(g) + 0.0722 * f(b);
        };
        let node = element, background = null;
        while (node && node.nodeType === 1) {
            const c = rgb(getComputedStyle(node).backgroundColor);
            if (c.length === 3 || (c.length === 4 && c[3] > 0.5)) { background = c; break; }
            node = node.parentElement;
        }
        background = background || [255, 255, 255];
        const a = luminance(rgb(getComputedStyle(element).color)), b = luminance(background);
        return (Math.max(a, b) + 0.05) / (Math.min(a, b) + 0.05);
    }"""


def contrast(page, element) -> float:
    """WCAG contrast ratio of ``element``'s (a locator or an element handle) text with its background."""
    handle = element.element_handle() if hasattr(element, "element_handle") else element
    return page.evaluate(CONTRAST, handle)


@contextlib.contextmanager
def offline_page(path: Path):
    """Debian's Chromium (headless) showing the file ``path`` with every request that is not
    for a file, ``data:`` or ``about:`` refused; yields ``(page, remote, dialogs)``: the page,
    the refused URLs and the messages of the dialogs it opened (each dismissed). Skips the test
    where Chromium is not installed (tests/system/test_browser.py installs it)."""
    sync_api = pytest.importorskip("playwright.sync_api")
    chromium = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
    if chromium is None:
        pytest.skip("Debian's chromium is not installed (tests/system/test_browser.py installs it)")
    with sync_api.sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium, headless=True,
                                             args=["--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage"])
        try:
            page = browser.new_page()
            remote: list[str] = []
            dialogs: list[str] = []
            page.on("dialog", lambda dialog: (dialogs.append(dialog.message), dialog.dismiss()))

            def route(request_route):
                url = request_route.request.url
                if url.startswith(("file://", "data:", "about:")):
                    request_route.continue_()
                else:
                    remote.append(url)
                    request_route.abort()

            page.route("**/*", route)
            page.goto(Path(path).as_uri())
            yield page, remote, dialogs
        finally:
            browser.close()
