"""The RT-core projection of study.bench.carry on rows made up here (numbers worked by hand below): a method is
scaled by texture rates, the exact query by the RT-core factor range, only cuda frozen rows are projected, and the
bench's Markdown says PROJECTION where (and only where) the GPU has no RT cores."""

import pytest

from study.bench.carry import projection_rows
from study.bench.output import write_bench_files

ROW = {
    "batch": "close-up",
    "backend": "cuda",
    "path": "frozen",
    "label": "localized(iterations=10)",
    "lookups_mean": 12.0,
    "bytes_per_ray": 13 * 16 + 64 + 53,
    "ms_per_frame": 0.043,
    "x_vs_preliminary": 3.5,  # the exact query: 0.1505 ms per frame in software
    "x_floor": 1.04,
}


def test_projection_by_hand():
    rows = projection_rows([ROW, {**ROW, "backend": "llvm"}, {**ROW, "path": "plain"}])
    assert [r["gpu"] for r in rows] == ["RTX 4090", "L40S"]  # only the cuda frozen row, once per target
    r = rows[0]
    assert r["ms_per_frame_projected"] == pytest.approx(0.043 * 1045 / 1290)  # 0.034834
    assert r["exact_ms_projected"] == pytest.approx(0.1505 / 4.3)  # 0.035
    assert r["x_vs_preliminary_low"] == pytest.approx((0.1505 / 5.0) / (0.043 * 1045 / 1290))  # 0.864
    assert r["x_vs_preliminary_high"] == pytest.approx((0.1505 / 3.5) / (0.043 * 1045 / 1290))  # 1.234


@pytest.mark.parametrize("rt", [False, True])
def test_bench_markdown_says_projection_only_without_rt_cores(tmp_path, rt):
    info = {
        "tag": "gpu",
        "cpu": "x",
        "cores": 1,
        "gpu": "NVIDIA H200",
        "python": "3",
        "numpy": "2",
        "drjit": "1",
        "mitsuba": "3",
        "embreex": "4",
        "libllvm": "",
        "rt_cores": "RT cores assumed present" if rt else "NVIDIA H200 has no RT cores: ...",
    }
    write_bench_files([ROW], info, tmp_path, lock=False)
    md = (tmp_path / "bench-gpu.md").read_text()
    assert ("PROJECTION, not a measurement" in md) is not rt
    assert (tmp_path / "projection-gpu.csv").exists() is not rt
