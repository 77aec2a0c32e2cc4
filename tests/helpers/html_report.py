"""Reading the self-contained HTML reports in tests: the verdict, its reasons, and a headless browser."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

#: Debian's Chromium (or another Chromium build) when installed, else None (the browser tests skip).
BROWSER = next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


def verdict_of(html: str) -> str:
    match = re.search(r"Verdict: <strong>([^<]+)</strong>", html)
    assert match, "no verdict in the report"
    return match.group(1)


def reasons_of(html: str) -> str:
    start = html.index('aria-label="verdict"')
    return html[start:html.index("</section>", start)]


def assert_self_contained(html: str) -> None:
    assert "<script" not in html
    assert not re.search(r"""(src|href)\s*=\s*["'](https?:)?//""", html), "a resource that needs the network"
    assert "@import" not in html and "url(http" not in html


#: Flags that keep the browser's own background traffic (updates, sync, accounts) quiet.
QUIET_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", "--no-first-run", "--disable-sync",
    "--disable-background-networking", "--disable-component-update", "--disable-default-apps",
    "--disable-domain-reliability", "--enable-logging=stderr", "--v=0",
)


def open_in_browser(page: Path, screenshot: Path, profile: Path, width: int = 412) -> tuple[list[str], list[str]]:
    """Load ``page`` in headless Chromium, save a screenshot; return (console messages, URLs the page requested)."""
    netlog = profile / "netlog.json"
    proc = subprocess.run(
        [BROWSER, *QUIET_FLAGS, f"--user-data-dir={profile}", f"--log-net-log={netlog}",
         f"--window-size={width},2400", f"--screenshot={screenshot}", page.resolve().as_uri()],
        capture_output=True, text=True, timeout=120,
    )
    assert screenshot.exists() and screenshot.stat().st_size > 1_000, proc.stderr[-2000:]
    console = [line for line in proc.stderr.splitlines() if ":CONSOLE" in line]
    log = json.loads(netlog.read_text())
    start_job = log["constants"]["logEventTypes"]["URL_REQUEST_START_JOB"]
    starts = [e.get("params", {}) for e in log["events"] if e["type"] == start_job]
    requested = [
        p["url"] for p in starts
        if "url" in p and p.get("initiator") != "not an origin"  # the page's requests, not the browser's own
        and not p["url"].startswith(("file:", "data:"))
    ]
    return console, requested
