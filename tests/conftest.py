"""Shared fixtures. Reference values are computed analytically (study.impostor.analytic) unless a test says
otherwise."""

import hashlib
import re
from pathlib import Path

import numpy as np
import pytest

from study import backend as backends
from study import runtime as llvm


def _llvm_ok() -> bool:
    try:
        llvm.require()
        return True
    except Exception:
        return False


BACKENDS = ["numpy"] + (["llvm"] if _llvm_ok() else [])

#: the analytic box room used throughout, relative to the reference point (4 × 3 × 4 m, reference at the centre)
BOX_LO = np.array([-2.0, -1.5, -2.0])
BOX_HI = np.array([2.0, 1.5, 2.0])


@pytest.fixture(params=BACKENDS)
def B(request):
    return backends.get(request.param)


def load_script(name: str):
    """The module ``scripts/<name>.py`` of this checkout, loaded as ``name`` (the scripts are not a package)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location(
        name, Path(__file__).resolve().parents[1] / "scripts" / f"{name}.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def small_scene_dict(**over):
    """A small, fast scene (cube 32², camera 40², few samples) as a dict; ``over`` replaces top-level tables."""
    d = {
        "room": {"min": [-2.0, 0.0, -2.0], "max": [2.0, 3.0, 2.0]},
        "light": {"position": [0.3, 2.6, -0.4], "intensity": [7.0, 7.0, 7.0]},
        "reference": {"point": [0.0, 1.5, 0.0]},
        "object": {
            "shape": "sphere",
            "center": [0.6, 1.2, 0.3],
            "radius": 0.4,
            "material": {"type": "conductor", "n": [0.155, 0.117, 0.138], "k": [4.83, 3.12, 2.15]},
        },
        "camera": {
            "eye": [-0.3, 1.7, -1.9],
            "target": [0.6, 1.1, 0.6],
            "up": [0.0, 1.0, 0.0],
            "fov": 75.0,
            "width": 40,
            "height": 40,
        },
        "render": {
            "cube_res": 32,
            "cube_spp": 4,
            "spp": 4,
            "max_depth": 3,
            "supersample": 1,
            "seed": 0,
            "fresnel": "exact",
        },
    }
    d.update(over)
    return d


def scene_toml(d: dict) -> str:
    """A scene dict (as :func:`small_scene_dict` makes) written as a TOML file's text."""

    def val(v):
        if isinstance(v, str):
            return f'"{v}"'
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(val(x) for x in v) + "]"
        return repr(v)

    return "\n".join(
        f"[{t}]\n" + "\n".join(f"{k} = {val(v)}" for k, v in tab.items()) + "\n" for t, tab in d.items()
    )


#: A progress line of a command (study.cli.progress), stamped with the seconds since the command began.
PROGRESS_LINE = re.compile(r"^\[\s*\d+\.\d s\] ")


def error_output(res) -> str:
    """A command's output without its progress lines: what one-line-error checks read."""
    return "\n".join(ln for ln in res.output.splitlines() if not PROGRESS_LINE.match(ln)).strip()


def run_cli(*args, **kw):
    """``study ARGS…`` run in this process (typer's CliRunner, output and exit code captured): the result with
    ``.exit_code``, ``.output`` and ``.exception``. Arguments may be paths or numbers (made text); keyword arguments
    go to ``CliRunner.invoke`` (``input=``, ``env=``, ``catch_exceptions=``)."""
    from typer.testing import CliRunner

    from study.cli import app

    return CliRunner().invoke(app, [str(a) for a in args], **kw)


def digest(d: Path) -> dict:
    """{file name: sha256} of every file under ``d``: what a refused command must leave unchanged."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(d.rglob("*")) if p.is_file()}


def assert_one_line_error(res, words, before, out, code=2):
    """A refused command: exit ``code``, one ``error:`` line holding ``words``, no traceback, ``out`` unchanged."""
    text = error_output(res)  # the error is one line; progress lines on stderr may precede it
    assert res.exit_code == code, res.output
    assert text.startswith("error: ") and "\n" not in text, text
    assert words in text, text
    assert "Traceback" not in text
    assert digest(out) == before


def camera_gltf(path: Path, V: np.ndarray, F: np.ndarray, eye, quat, yfov: float, aspect: float) -> None:
    """A small glTF written by a test: one mesh (vertices ``V`` (n, 3), triangles ``F`` (m, 3)) and a perspective
    camera node at ``eye`` rotated by ``quat`` (x, y, z, w), ``yfov`` (radians) and ``aspect`` (width / height);
    its buffer a data URI."""
    import base64
    import json

    V, F = np.asarray(V, np.float32), np.asarray(F, np.uint16)
    blob = F.tobytes() + V.tobytes()
    g = {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0}, {"camera": 0, "translation": list(map(float, eye)), "rotation": list(map(float, quat))}],
        "cameras": [
            {"type": "perspective", "perspective": {"yfov": yfov, "aspectRatio": aspect, "znear": 0.01}}
        ],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 1}, "indices": 0}]}],
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": F.nbytes},
            {"buffer": 0, "byteOffset": F.nbytes, "byteLength": V.nbytes},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5123, "count": F.size, "type": "SCALAR"},
            {"bufferView": 1, "componentType": 5126, "count": len(V), "type": "VEC3",
             "min": V.min(0).tolist(), "max": V.max(0).tolist()},
        ],
    }  # fmt: skip
    path.write_text(json.dumps(g))
