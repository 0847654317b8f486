"""A public corpus (tests/assets/corpus/: 31 files made by others, sources, commits and licences in its README and
manifest.json; 11 generated here by scripts/make_corpus_generated.py): every file loads as its format says — and
agrees with a second reader — or is refused in one line naming what is refused.

The second reader is trimesh (triangles, world bounds after node transforms, and glTF base colours), for the files
it reads faithfully; where it does not, the case is named here and tested as trimesh's failure
(:func:`test_real_files.test_trimesh_misreads_tabs_and_indentation`,
:func:`test_real_files.test_trimesh_counts_negative_indices_from_the_end_of_the_file`). Triangle counts in the
manifest were taken by the corpus's collector with trimesh and an independent walk of the glTF JSON, before study's
readers read them.
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from study.errors import StudyError
from study.scene.environment import geometry

CORPUS = Path(__file__).resolve().parents[1] / "assets" / "corpus"
MANIFEST = json.loads((CORPUS / "manifest.json").read_text())
LOADS = [e for e in MANIFEST if e["expect"] == "load"]
REFUSED = [e for e in MANIFEST if e["expect"] == "refuse"]

#: files trimesh 4 cannot read as their format says (study reads them; the reason is the test's id)
TRIMESH_WRONG = {
    "obj/mcguire-cornell/CornellBox-Original.obj": "tab-separated v lines (trimesh drops them)",
    "gltf/Box/glTF-Draco/Box.gltf": "Draco (trimesh has no decoder)",
    "gltf/SimpleSparseAccessor/glTF/SimpleSparseAccessor.gltf": "sparse accessors (trimesh ignores them)",
    "gltf/meshoptimizer-pirate/pirate.glb": "EXT_meshopt_compression (trimesh has no decoder)",
    "obj/tinyobjloader/cornell_box.obj": "negative indices counted from the file's end, not the face's line (trimesh "
    "puts the ceiling's quads on the last object's vertices: its bounds top at y = 330, the ceiling is at 548.8)",
}
#: what each refused file is refused for: words its one line holds
REFUSAL = {
    "obj/tinyobjloader/invalid-relative-vertex-index.obj": "refers past the end of the list",
    "obj/tinyobjloader/issue-140-zero-face-idx.obj": "index 0",
    "xml/mitsuba-data/tests/scenes/various_shapes/test_various_shapes_path.xml": "outside the scene's folder",
}


def load(entry: dict):
    kind = "mitsuba" if entry["format"] == "xml" else "mesh"
    return geometry({"type": kind, "file": str(CORPUS / entry["path"])})


def test_the_corpus_is_what_its_readme_says():
    """≥ 16 files, each ≤ 2 MB, each with its source, commit and licence (or, generated here, the script that
    writes it and its bytes' SHA-256); every file in the folder accounted for."""
    import hashlib

    assert len(MANIFEST) >= 16
    for e in MANIFEST:
        if e.get("generated"):
            assert (CORPUS.parents[2] / e["generated"]).is_file() and e["license"], e["path"]
            assert hashlib.sha256((CORPUS / e["path"]).read_bytes()).hexdigest() == e["sha256"], e["path"]
            continue
        assert e["source"] and len(e["commit"]) == 40 and e["license"], e["path"]
    readme = (CORPUS / "README.md").read_text()
    for f in CORPUS.rglob("*"):
        if f.is_file():
            assert f.stat().st_size <= 2 * 2**20, f
            if f.name not in ("README.md", "manifest.json", ".gitattributes"):
                assert f.name in readme, f"{f} is not in the corpus README"


def test_the_corpus_has_the_kinds_of_scene_that_once_measured_wrong():
    """≥ 40 entry files, among them flat files, single objects, scenes far from the origin and in millimetres or
    kilometres, files with cameras and a Mitsuba scene with a shape in between (scripts/make_corpus_generated.py)."""
    assert len(MANIFEST) >= 40
    words = " ".join(" ".join(e["features"]) for e in MANIFEST)
    for kind in (
        "flat",
        "single object",
        "from the origin",
        "millimetres",
        "kilometres",
        "camera",
        "between",
    ):
        assert kind in words, kind


@pytest.mark.parametrize("entry", LOADS, ids=[e["path"] for e in LOADS])
def test_every_corpus_file_loads_with_its_triangles(entry):
    env = load(entry)
    n = len(env.mesh.faces)
    dropped = 0
    if "degenerate triangle" in env.summary:
        dropped = int(env.summary.split("dropped: ")[1].split(" degenerate")[0].replace(",", ""))
    if entry["triangles"] is not None:
        assert n + dropped == entry["triangles"], env.summary
    assert np.isfinite(env.mesh.vertices).all() and n > 0


SECOND = [e for e in LOADS if e["format"] != "xml" and e["path"] not in TRIMESH_WRONG]


@pytest.mark.parametrize("entry", SECOND, ids=[e["path"] for e in SECOND])
def test_trimesh_agrees_on_triangles_and_world_bounds(entry):
    import trimesh

    env = load(entry)
    sc = trimesh.load(str(CORPUS / entry["path"]), force="scene", process=False)
    geoms = [g for g in sc.dump(concatenate=False) if isinstance(g, trimesh.Trimesh) and len(g.faces)]
    V = np.concatenate([g.vertices for g in geoms])
    n_tm = sum(len(g.faces) for g in geoms)
    dropped = 0
    if "degenerate triangle" in env.summary:
        dropped = int(env.summary.split("dropped: ")[1].split(" degenerate")[0].replace(",", ""))
    assert len(env.mesh.faces) + dropped == n_tm
    np.testing.assert_allclose(env.bounds[0], V.min(0), atol=1e-5)
    np.testing.assert_allclose(env.bounds[1], V.max(0), atol=1e-5)


GLTF_COLOURS = [e for e in SECOND if e["format"] in ("gltf", "glb")]


@pytest.mark.parametrize("entry", GLTF_COLOURS, ids=[e["path"] for e in GLTF_COLOURS])
def test_gltf_base_colours_agree_with_trimesh(entry):
    """Each part's constant linear base colour (baseColorFactor, as the spec says: linear) against trimesh's
    material of the same name (8-bit, so within 1/255)."""
    import trimesh

    env = load(entry)
    sc = trimesh.load(str(CORPUS / entry["path"]), force="scene", process=False)
    theirs = {}
    for g in sc.geometry.values():
        mat = getattr(g.visual, "material", None)
        if mat is not None and getattr(mat, "baseColorFactor", None) is not None and mat.name:
            theirs[mat.name] = np.asarray(mat.baseColorFactor[:3], float) / 255
    compared = 0
    for p in env.parts:
        name = p.name.split(":", 1)[-1]
        if p.color is not None and name in theirs:
            np.testing.assert_allclose(p.color, theirs[name], atol=1 / 255 + 1e-6, err_msg=name)
            compared += 1
    assert compared or not theirs, (env.parts, theirs)


@pytest.mark.parametrize("entry", REFUSED, ids=[e["path"] for e in REFUSED])
def test_corpus_files_outside_what_study_reads_are_refused_in_one_line(entry):
    with pytest.raises(StudyError) as e:
        load(entry)
    msg = str(e.value)
    assert REFUSAL[entry["path"]] in msg and "\n" not in msg, msg


def test_the_meshopt_pirate_decodes_to_its_accessors_bounds():
    """pirate.glb (EXT_meshopt_compression, KHR_mesh_quantization): its decoded uint16 positions, dequantized by
    the node's scale and translation, span exactly the POSITION accessor's min and max that the file states."""
    from study.scene.references import gltf_json

    p = CORPUS / "gltf/meshoptimizer-pirate/pirate.glb"
    g = gltf_json(p)
    acc = g["accessors"][g["meshes"][0]["primitives"][0]["attributes"]["POSITION"]]
    node = g["nodes"][0]
    lo = np.asarray(acc["min"]) * node["scale"] + node["translation"]
    hi = np.asarray(acc["max"]) * node["scale"] + node["translation"]
    env = load({"format": "glb", "path": "gltf/meshoptimizer-pirate/pirate.glb"})
    np.testing.assert_allclose(env.bounds[0], lo, atol=1e-6)
    np.testing.assert_allclose(env.bounds[1], hi, atol=1e-6)


def test_the_published_mcguire_cornell_box_runs_with_its_ceiling_light_lit():
    """Tabs, CR LF, negative indices, quads and ``Ke``: read whole, the light an area light of radiance (17, 12, 4)."""
    env = load({"format": "obj", "path": "obj/mcguire-cornell/CornellBox-Original.obj"})
    light = [p for p in env.parts if p.emission is not None]
    assert len(light) == 1 and light[0].emission == (17.0, 12.0, 4.0), env.summary


# ---------------------------------------------------------------------------------------------- slow: a whole run
@pytest.mark.slow
@pytest.mark.parametrize("entry", MANIFEST, ids=[e["path"] for e in MANIFEST])
def test_study_run_on_every_corpus_file(entry, tmp_path):
    """``study run FILE -m classical -m localized`` at 48²: exit 0 and a PNG, or exit 2 with one line that names
    what is refused (the file's feature; or the placement that an open scene cannot give, issue 44, a skip with its
    line)."""
    out = tmp_path / "o"
    small = ["camera.width=48", "camera.height=48", "render.cube_res=32", "render.spp=4", "render.cube_spp=4"]
    cmd = [sys.executable, "-m", "study.cli", "run", str(CORPUS / entry["path"]), "-m", "classical", "-m",
           "localized", "--out", str(out), "--cache", str(tmp_path / "c")]  # fmt: skip
    cmd += [a for s in small for a in ("--set", s)]
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path, timeout=900)
    if entry["expect"] == "refuse":
        assert res.returncode == 2, res.stderr[-2000:]
        assert REFUSAL[entry["path"]] in res.stderr and "Traceback" not in res.stderr, res.stderr[-2000:]
        return
    if res.returncode == 2:  # an open scene (one object seen from outside), or the file's own view: placement
        placement = ("enclosed", "leave the scene", "fully on the object")
        assert "Traceback" not in res.stderr and any(w in res.stderr for w in placement), res.stderr[-2000:]
        pytest.skip("placement: " + res.stderr.strip().splitlines()[-1][:200])
    assert res.returncode == 0, res.stderr[-2000:]
    assert list(out.rglob("*.png")), list(out.rglob("*"))
    import pandas as pd

    from study.measure import worth

    row = (
        pd.read_csv(out / "table.csv").iloc[0].to_dict()
    )  # the case's worth columns (study/measure/worth.py)
    said = [ln for ln in res.stderr.splitlines() if "not worth looking at" in ln]
    line = worth.verdict(row)
    assert len(said) == (1 if line else 0) and (not line or line in said[0]), (said, line)
