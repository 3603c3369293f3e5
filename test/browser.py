"""Open a local HTML page in Debian's headless Chromium and say what a reader's browser saw.

Playwright drives the system's /usr/bin/chromium (installed by launch_scripts/setup_env.sh)
over its DevTools pipe; it never downloads a browser of its own. The page is opened as a
file:// URL: the report is one self-contained file, so nothing is served, and Chromium reports
console messages, script errors and failed loads of file:// pages as of any other.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

from playwright.sync_api import ConsoleMessage, Dialog, Request, sync_playwright

# Playwright adds most of these itself (and a fresh temporary --user-data-dir, which it
# refuses as an argument); they are named here so the launch does not depend on its defaults.
# Without the network ones, Chromium on this offline machine keeps trying to reach Google's
# services and logs every refused connection. --no-sandbox: Chromium's sandbox refuses root.
CHROMIUM_ARGS = (
    '--headless',
    '--no-sandbox',
    '--disable-gpu',
    '--disable-quic',
    '--no-first-run',
    '--disable-background-networking',
    '--disable-component-update',
    '--disable-sync',
)
# Console levels that mean something on the page is wrong.
REPORTED_CONSOLE_LEVELS = ('error', 'warning')
TIMEOUT_MS = 60_000  # a report with its figures embedded is several MB of HTML

# Every <img> as the browser has it once the page has loaded (the load event waits for images).
_IMAGES_JS = """() => Array.from(document.images, image => ({
    alt: image.getAttribute('alt'), complete: image.complete,
    natural_width: image.naturalWidth, natural_height: image.naturalHeight,
    figure_id: image.closest('figure') ? image.closest('figure').id : null}))"""
# The page's height as loaded, then with every <details> opened (as a reader clicking them).
_HEIGHTS_JS = """() => {
    const folded = document.documentElement.scrollHeight;
    for (const details of document.querySelectorAll('details')) { details.open = true; }
    return [folded, document.documentElement.scrollHeight];
}"""
_TAG_COUNTS_JS = """() => {
    const counts = {};
    for (const element of document.getElementsByTagName('*')) {
        const tag = element.tagName.toLowerCase();
        counts[tag] = (counts[tag] || 0) + 1;
    }
    return counts;
}"""


@dataclass(frozen=True)
class Image:
    """One <img> of the page: its alt text (None when it has none) and whether it decoded."""

    alt: str | None
    complete: bool
    natural_width: int
    natural_height: int
    figure_id: str | None  # id of the <figure> holding it, if any


@dataclass(frozen=True)
class Visit:
    """What the browser saw: the rendered text, the elements, and every complaint."""

    title: str
    body_text: str  # document.body.innerText: the text as rendered, not the markup
    console: list[tuple[str, str]]  # (level, text) of console errors and warnings
    page_errors: list[str]  # uncaught exceptions in the page's scripts
    failed_requests: list[str]  # 'url: reason' of every load that failed
    dialogs: list[str]  # 'type: message' of every alert/confirm/prompt that opened
    images: list[Image]
    tag_counts: dict[str, int]  # elements of the document by tag name
    height_px: int  # the page's height as loaded (folded <details> closed)
    height_open_px: int  # its height once every <details> is opened


def chromium_path() -> str:
    """/usr/bin/chromium, or an error saying how to get it (the test must not skip)."""
    path = shutil.which('chromium')
    if path is None:
        raise RuntimeError(
            "Debian's chromium is not on PATH: run launch_scripts/setup_env.sh "
            '(as root it installs it with apt-get)'
        )
    return path


def visit(page_path: str | Path) -> Visit:
    """Load a local HTML file in headless Chromium and collect what it rendered and reported."""
    url = Path(page_path).resolve().as_uri()
    console: list[tuple[str, str]] = []
    page_errors: list[str] = []
    failed: list[str] = []
    dialogs: list[str] = []

    def on_console(message: ConsoleMessage) -> None:
        if message.type in REPORTED_CONSOLE_LEVELS:
            console.append((message.type, message.text))

    def on_request_failed(request: Request) -> None:
        failed.append(f'{request.url[:200]}: {request.failure}')

    def on_dialog(dialog: Dialog) -> None:
        dialogs.append(f'{dialog.type}: {dialog.message}')
        dialog.dismiss()

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=chromium_path(),
            headless=True,
            args=list(CHROMIUM_ARGS),
            timeout=TIMEOUT_MS,
        )
        try:
            page = browser.new_page()
            page.on('console', on_console)
            page.on('pageerror', lambda error: page_errors.append(str(error)))
            page.on('requestfailed', on_request_failed)
            page.on('dialog', on_dialog)
            page.goto(url, wait_until='load', timeout=TIMEOUT_MS)
            images = [Image(**image) for image in page.evaluate(_IMAGES_JS)]
            tags = page.evaluate(_TAG_COUNTS_JS)
            body_text = page.inner_text('body')
            height_px, height_open_px = page.evaluate(_HEIGHTS_JS)
            return Visit(
                title=page.title(),
                body_text=body_text,
                console=console,
                page_errors=page_errors,
                failed_requests=failed,
                dialogs=dialogs,
                images=images,
                tag_counts=tags,
                height_px=height_px,
                height_open_px=height_open_px,
            )
        finally:
            browser.close()
