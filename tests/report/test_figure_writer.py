"""A figure's per-case files (multi-layer EXR, viewer images) are encoded by a background writer while the next case
runs (issue 41, outputs off the critical path): made off the main thread, and the same bytes and manifest as when
they were made after the last case (the viewer starts at the figure's exposure, known only then)."""

import json
import threading

from conftest import run_cli

from study.outputs import viewer
from tests.test_cli import SMALL


def test_case_files_are_made_beside_the_next_case(tmp_path, monkeypatch):
    made_on = []
    real = viewer.case_files

    def spy(*a, **k):
        made_on.append(threading.current_thread() is threading.main_thread())
        return real(*a, **k)

    monkeypatch.setattr(viewer, "case_files", spy)
    cfg = tmp_path / "f.toml"
    cfg.write_text(
        SMALL.format(iterations="[10]").replace("width = 48, height = 48", "width = 24, height = 24")
    )
    res = run_cli("figure", "fig4", "--config", str(cfg), "--out", str(tmp_path / "o"), "--cache",
                                   str(tmp_path / "c"))  # fmt: skip
    assert res.exit_code == 0, res.output
    assert made_on == [False, False, False]  # three positions, each encoded by the writer thread
    meta = json.loads((tmp_path / "o" / "metadata.json").read_text())
    entries = json.loads((tmp_path / "o" / viewer.MANIFEST).read_text())["cases"]
    assert [e["exposure_ev"] for e in entries] == [round(meta["exposure_ev"], 2)] * 3
    assert len(list((tmp_path / "o" / "exr").glob("*.exr"))) == 3


def test_panel_titles_wrap_long_parameter_lists():
    """A label's parameters break after a comma once a line would pass 26 characters (fig_probes' ssr with its
    fallback ran into the next panel's title)."""
    from study.outputs.figures import _wrap

    assert _wrap("proxy_box") == "proxy_box"
    assert _wrap("localized(iterations=10)") == "localized\n(iterations=10)"
    assert _wrap("ssr(max_steps=512, fallback='localized')") == "ssr\n(max_steps=512,\nfallback='localized')"
    assert all(len(line) <= 26 for line in _wrap("ssr(max_steps=512, fallback='localized')").splitlines())
