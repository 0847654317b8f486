"""Screenshots of the report page for docs/screenshots/ (headless Chromium through Playwright):
`python scripts/screenshots.py [REPORTS]` — the top (headline and summary), a figure's viewers with the
difference view on, and a run's page when reports/run-*/ exists."""

import shutil
import sys
from pathlib import Path

from playwright.sync_api import sync_playwright

ROOT = Path(__file__).resolve().parents[1]
reports = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "reports"
out = ROOT / "docs" / "screenshots"
out.mkdir(parents=True, exist_ok=True)
exe = shutil.which("chromium") or "/usr/bin/chromium"
args = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update"]
with sync_playwright() as p:
    b = p.chromium.launch(executable_path=exe, args=args)
    page = b.new_page(viewport={"width": 1400, "height": 1000})
    page.goto((reports / "index.html").as_uri())
    page.wait_for_timeout(800)
    page.screenshot(path=str(out / "report-top.png"))
    viewer = page.locator(".viewer").first
    if viewer.count():
        viewer.scroll_into_view_if_needed()
        viewer.click()
        page.keyboard.press("d")
        page.wait_for_timeout(400)
        page.screenshot(path=str(out / "report-viewer.png"))
    b.close()
print("wrote", *sorted(p.name for p in out.glob("*.png")))
