"""index.html in a real browser: headless Chromium (Debian's, driven by Playwright for Python) opens a small report
as file:// and checks that every image loads, that every viewer image decodes to the numbers in the EXRs, that a
key press and the exposure slider change the shown pixels, that a click on a header sorts a table, and that the
console stays free of errors. A screenshot is kept in $STUDY_ARTIFACTS (default tests/artifacts/, gitignored).

Skipped, with one line saying why, where Playwright or a Chromium cannot be found or started (scripts/setup.sh
installs both: Debian's ``chromium`` as root, ``playwright`` from the test extras)."""

import os
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_report_html import small_report

from study.io import read_exr_layers

ROOT = Path(__file__).resolve().parents[1]


def _chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        if path := shutil.which(name):
            return path
    pytest.skip("no Chromium found (scripts/setup.sh installs Debian's chromium when run as root)")


@pytest.fixture(scope="module")
def browser():
    sync = pytest.importorskip(
        "playwright.sync_api", reason="playwright not installed (pip install -e '.[test]')"
    )
    exe = _chromium()
    with sync.sync_playwright() as p:
        try:
            b = p.chromium.launch(executable_path=exe, args=["--no-sandbox"])
        except Exception as err:  # a browser that cannot start here
            pytest.skip(f"Chromium at {exe} does not start: {str(err).splitlines()[0][:160]}")
        yield b
        b.close()


@pytest.fixture
def page(browser, tmp_path_factory):
    reports = small_report(tmp_path_factory)
    pg = browser.new_page(viewport={"width": 1300, "height": 950})
    errors = []
    pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto((reports / "index.html").as_uri())
    pg.wait_for_load_state("load")
    yield pg, reports, errors
    pg.close()


def _pixels(pg, i=0) -> str:
    """A digest of what viewer ``i``'s canvas shows (FNV-1a over its RGBA bytes, computed in the page)."""
    h, opaque = pg.evaluate(f"""() => {{ const c = document.querySelectorAll('.viewer canvas.view')[{i}];
        const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
        let h = 2166136261, n = 0;
        for (let k = 0; k < d.length; k++) {{ h = Math.imul(h ^ d[k], 16777619) >>> 0; if (k % 4 === 3 && d[k]) n++; }}
        return [h, n]; }}""")
    assert opaque > 0, "the canvas is empty"
    return f"{h:08x}"


def _settle(pg):
    pg.wait_for_function("() => window.studyViewers.every(v => v.img)", timeout=15000)
    pg.wait_for_timeout(150)


def test_report_in_chromium(page):
    pg, reports, errors = page
    # every <img> loaded
    broken = pg.evaluate(
        "() => Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src)"
    )
    assert pg.evaluate("document.images.length") >= 1 and not broken, broken
    # every viewer image decodes, and what the page decodes is what the EXR holds
    res = pg.evaluate("window.studyCheckViewers()")
    c = pg.evaluate("window.studyViewers[0].c")
    total = pg.evaluate("window.studyViewers.reduce((n, v) => n + v.c.layers.length, 0)")
    assert res["viewers"] == 2 and not res["failed"] and res["layers"] == total >= 2 * 15, res
    i = next(k for k, la in enumerate(c["layers"]) if la["source"] == "classical" and la["layer"] == "image")
    y0, x0, h, w = c["crop"]
    exr = read_exr_layers(reports / c["layers"][i]["exr"])[c["layers"][i]["exr_layer"]]
    for x, y in ((w // 2, h // 2), (1, 1), (w - 2, h // 3)):
        got = np.array(pg.evaluate(f"window.studyViewers[0].valueAt({i}, {x}, {y})"))
        want = exr[y0 + y, x0 + x]
        assert np.allclose(got, want, rtol=2**-7, atol=want.max() * 2**-8), (x, y, got, want)

    # the viewer: keys switch the image, the slider changes the exposure
    pg.locator(".viewer").first.scroll_into_view_if_needed()
    _settle(pg)
    before = _pixels(pg)
    pg.locator(".viewer canvas.view").first.click()
    pg.keyboard.press("ArrowRight")
    _settle(pg)
    after_key = _pixels(pg)
    assert after_key != before, "a key press did not change the shown image"
    assert pg.locator(".viewer .shown").first.inner_text().startswith("localized(iterations=1)")
    pg.keyboard.press("1")
    _settle(pg)
    assert pg.locator(".viewer .shown").first.inner_text().startswith("truth_at_hit")
    truth = _pixels(pg)
    pg.evaluate("""() => { const s = document.querySelector('.viewer input.exposure'); s.value = '2';
                           s.dispatchEvent(new Event('input')); }""")
    pg.wait_for_timeout(150)
    assert _pixels(pg) != truth, "the exposure slider did not change the pixels"
    pg.keyboard.press("2")
    pg.keyboard.press("ArrowDown")  # the angular-error layer of classical
    _settle(pg)
    assert "angular error" in pg.locator(".viewer .shown").first.inner_text()
    pg.keyboard.press("+")
    pg.wait_for_timeout(100)
    shots = Path(os.environ.get("STUDY_ARTIFACTS", ROOT / "tests" / "artifacts"))
    shots.mkdir(parents=True, exist_ok=True)
    pg.keyboard.press("ArrowUp")
    _settle(pg)
    pg.locator(".viewers").first.screenshot(path=str(shots / "report-viewer.png"))
    print(f"screenshot: {shots / 'report-viewer.png'}")

    # a click on a header sorts the table by that column
    table = pg.locator("table.sortable").filter(has_text="rmse_truth_debiased").last
    col = pg.evaluate(
        """(t) => Array.from(t.tHead.rows[0].cells).findIndex(c => c.textContent === 'label')""",
        table.element_handle(),
    )
    labels = lambda: table.locator(f"tbody tr td:nth-child({col + 1})").all_inner_texts()  # noqa: E731
    first = labels()
    table.locator("th", has_text="label").first.click()
    asc = labels()
    assert asc == sorted(first) and asc != first
    table.locator("th", has_text="label").first.click()
    assert labels() == sorted(first, reverse=True)
    assert not errors, errors


def test_missing_viewer_images_are_said_not_errors(browser, tmp_path_factory):
    """A case whose viewer script is gone (and no EXRs): that viewer says what is missing, the other still shows
    its images, and the console stays clean."""
    from typer.testing import CliRunner

    from study.cli import app

    reports = small_report(tmp_path_factory)
    (reports / "fig4" / "viewer" / "fig4-p1.js").unlink()
    shutil.rmtree(reports / "fig4" / "exr")
    assert CliRunner().invoke(app, ["report", "--reports", str(reports)]).exit_code == 0
    pg = browser.new_page(viewport={"width": 1300, "height": 950})
    errors = []
    pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.goto((reports / "index.html").as_uri())
    pg.locator(".viewer").first.scroll_into_view_if_needed()
    pg.wait_for_function("() => window.studyViewers[0].img", timeout=15000)
    msgs = pg.locator(".viewer .msg").all_inner_texts()
    assert msgs[0] == "" and "images missing: fig4/viewer/fig4-p1.js" in msgs[1], msgs
    assert "EXR not in this copy" in pg.locator(".viewer .links").first.inner_text()
    _pixels(pg, 0)
    res = pg.evaluate("window.studyCheckViewers()")
    assert res["layers"] == len(pg.evaluate("window.studyViewers[0].c.layers")) and len(res["failed"]) > 0
    assert not errors, errors
    pg.close()
