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
from conftest import run_cli

from study.io import read_exr_layers
from tests.report.test_report_html import small_report

ROOT = Path(__file__).resolve().parents[2]


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
    pg.keyboard.press("4")  # the references first: 1 truth_at_hit, 2 oracle_map, 3 mitsuba, 4 classical
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

    reports = small_report(tmp_path_factory)
    (reports / "fig4" / "viewer" / "fig4-p1.js").unlink()
    shutil.rmtree(reports / "fig4" / "exr")
    assert run_cli("report", "--reports", str(reports)).exit_code == 0
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


# ---------------------------------------------------------------------------------------------- issue 26 (8)
def _shown(pg, i=0) -> str:
    return pg.locator(".viewer .shown").nth(i).inner_text()


def test_table_headers_stick_under_the_top_bar(page):
    """A table scrolled past the top keeps its header row visible just under the bar (its height, as many lines as
    its links need: --bar), and a header click there still sorts; a table wider than the page scrolls in its own
    box, its header at the box's top."""
    pg, _, errors = page
    table = pg.locator(".tablebox:not(.scroll) table.sortable").filter(has_text="holds").last  # the claims
    box = table.bounding_box()
    assert box["height"] > 150, box
    bar = pg.evaluate("document.querySelector('nav.toc').getBoundingClientRect().bottom")
    assert 28 <= bar <= 80 and pg.evaluate(
        "parseFloat(getComputedStyle(document.documentElement).getPropertyValue('--bar'))"
    ) == pytest.approx(bar, abs=0.5), bar
    wide = pg.locator(".tablebox.scroll").first  # wider than the page: its own box, scrolled inside
    assert wide.evaluate("b => b.scrollWidth > b.clientWidth")
    got = wide.evaluate("""b => { b.scrollTop = 60; b.scrollLeft = 40;
        const h = b.querySelector('thead th').getBoundingClientRect();
        return Math.abs(h.top - b.getBoundingClientRect().top) <= 1.5; }""")
    assert got, "the header of a table in its box does not stay at the box's top"
    pg.evaluate(
        "document.body.appendChild(Object.assign(document.createElement('div'), {style: 'height:3000px'}))"
    )
    pg.evaluate(f"window.scrollTo(0, {box['y'] - bar + 90})")  # the table's top 90 px above the bar's bottom
    pg.wait_for_timeout(100)
    th = pg.evaluate(
        """(t) => { const h = t.tHead.rows[0].cells[0].getBoundingClientRect();
        const hit = document.elementFromPoint(h.left + 3, h.top + h.height / 2);
        return {top: h.top, isHeader: !!hit && !!hit.closest('thead')}; }""",
        table.element_handle(),
    )
    assert abs(th["top"] - bar) <= 1.5 and th["isHeader"], (th, bar)
    # a viewer title scrolled to is not under the bar
    pg.locator(".viewer").first.focus()
    pg.evaluate("document.querySelector('.viewers').scrollIntoView()")
    pg.wait_for_timeout(100)
    top = pg.evaluate("document.querySelector('.viewer .title').getBoundingClientRect().top")
    assert top >= bar, (top, bar)
    assert not errors, errors


def test_number_keys_reach_every_image_reference_first(page):
    pg, _, errors = page
    pg.locator(".viewer").first.scroll_into_view_if_needed()
    _settle(pg)
    sources = pg.evaluate("window.studyViewers[0].sources")
    assert sources[:3] == ["truth_at_hit", "oracle_map", "mitsuba"] and "classical" in sources
    buttons = pg.locator(".viewer").first.locator(".row.sources button").all_inner_texts()
    assert buttons == [f"{i + 1} {s}" for i, s in enumerate(sources)]
    pg.locator(".viewer canvas.view").first.click()
    for k, s in enumerate(sources):
        pg.keyboard.press(str(k + 1))
        _settle(pg)
        assert _shown(pg).startswith(s + " —"), (k, _shown(pg))
    # more than nine: two digits typed quickly are one number (1, 4 → the 14th)
    got = pg.evaluate("""() => { const v = window.studyViewers[0], saved = v.sources;
        v.sources = Array.from({length: 14}, (_, i) => 's' + i); v.lastDigit = 0;
        v.pickDigit('1'); const one = v.src; v.pickDigit('4'); const fourteen = v.src;
        v.lastDigit = 0; v.pickDigit('0'); const ten = v.src; v.sources = saved; return [one, fourteen, ten]; }""")
    assert got == [0, 13, 9], got
    assert not errors, errors


def test_viewers_of_a_figure_share_exposure_and_zoom(page):
    import json

    pg, reports, errors = page
    pg.locator(".viewer").first.scroll_into_view_if_needed()
    _settle(pg)
    # they start at the exposure of the figure's grid PNG (manifest exposure_ev), not at 0 EV
    manifest = json.loads(next(reports.glob("*/viewer/index.json")).read_text())
    want = manifest["cases"][0]["exposure_ev"]
    assert want != 0  # the small scene's exposure rule gives a non-zero value: this can fail
    assert pg.evaluate("window.studyViewers[0].exposure") == pytest.approx(want)
    assert float(pg.locator(".viewer input.exposure").first.input_value()) == pytest.approx(want)
    before = _pixels(pg, 1)
    pg.evaluate("""() => { const s = document.querySelector('.viewer input.exposure'); s.value = '3';
                           s.dispatchEvent(new Event('input')); }""")
    pg.wait_for_timeout(150)
    assert pg.evaluate("window.studyViewers.map(v => v.exposure)") == [3, 3]
    assert pg.locator(".viewer input.exposure").nth(1).input_value() == "3"
    assert _pixels(pg, 1) != before, "the second viewer did not take the exposure"
    pg.locator(".viewer canvas.view").first.click()
    pg.keyboard.press("+")
    pg.wait_for_timeout(100)
    mags = pg.evaluate("window.studyViewers.map(v => v.view().mag)")
    assert mags[0] == pytest.approx(1.5) and mags[1] == pytest.approx(1.5), mags
    assert not errors, errors


def test_ab_flip_and_difference_against_the_reference(page):
    pg, reports, errors = page
    pg.locator(".viewer").first.scroll_into_view_if_needed()
    _settle(pg)
    pg.locator(".viewer canvas.view").first.click()
    pg.keyboard.press("1")
    _settle(pg)
    truth = _pixels(pg)
    pg.keyboard.press("4")
    _settle(pg)
    assert _shown(pg).startswith("classical —")
    method = _pixels(pg)
    assert method != truth
    pg.keyboard.press("r")  # A/B: the reference in place of classical
    _settle(pg)
    assert _shown(pg).startswith("truth_at_hit —") and "a/b against classical" in _shown(pg)
    assert _pixels(pg) == truth
    pg.keyboard.press("r")
    _settle(pg)
    assert _pixels(pg) == method and _shown(pg).startswith("classical —")
    pg.keyboard.press("d")  # |classical − truth_at_hit|
    _settle(pg)
    assert "difference" in _shown(pg) and _pixels(pg) not in (truth, method)
    c = pg.evaluate("window.studyViewers[0].c")
    i = next(k for k, la in enumerate(c["layers"]) if la["source"] == "classical" and la["layer"] == "image")
    t = next(
        k for k, la in enumerate(c["layers"]) if la["source"] == "truth_at_hit" and la["layer"] == "image"
    )
    y0, x0, h, w = c["crop"]
    x, y = w // 2, h // 2
    a = np.array(pg.evaluate(f"window.studyViewers[0].valueAt({i}, {x}, {y})"))
    b = np.array(pg.evaluate(f"window.studyViewers[0].valueAt({t}, {x}, {y})"))
    d = np.array(
        pg.evaluate(
            f"(() => {{ const v = window.studyViewers[0]; const k = ({y} * v.img.w + {x}) * 3;"
            " return Array.from(v.img.data.slice(k, k + 3)); })()"
        )
    )
    assert np.allclose(d, np.abs(a - b), rtol=1e-5, atol=1e-7), (d, a, b)
    assert "|difference|" in pg.locator(".viewer .legend").first.inner_text()
    pg.keyboard.press("d")
    _settle(pg)
    assert _pixels(pg) == method
    shots = Path(os.environ.get("STUDY_ARTIFACTS", ROOT / "tests" / "artifacts"))
    shots.mkdir(parents=True, exist_ok=True)
    pg.screenshot(path=str(shots / "report-page.png"))
    assert not errors, errors


def test_no_script_from_a_name_runs(browser, tmp_path):
    """Case, method and file names with HTML, Markdown links to javascript: and Rich markup: the page shows them
    as text, runs none of them, and its viewers still work."""
    from tests.report.test_names_and_markup import evil_report

    reports = evil_report(tmp_path)
    pg = browser.new_page(viewport={"width": 1300, "height": 950})
    errors, dialogs = [], []
    pg.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    pg.on("pageerror", lambda e: errors.append(str(e)))
    pg.on("dialog", lambda d: (dialogs.append(d.message), d.dismiss()))
    pg.goto((reports / "index.html").as_uri())
    pg.wait_for_load_state("load")
    hrefs = pg.evaluate("Array.from(document.querySelectorAll('[href],[src]')).map(e => e.href || e.src)")
    assert not [h for h in hrefs if h.lower().startswith("javascript:")], hrefs
    for a in pg.locator("a").all()[:60]:
        href = a.get_attribute("href") or ""
        if not href.startswith("#"):
            continue
        a.click()
    res = pg.evaluate("window.studyCheckViewers()")
    assert res["viewers"] == 5 and not res["failed"], res
    assert "<img src=x onerror=alert(1)>[/x]" in pg.locator("body").inner_text()
    pg.wait_for_timeout(300)
    assert not dialogs and not errors, (dialogs, errors)
    pg.close()
