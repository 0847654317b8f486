"""Make the small test meshes shipped in ``scenes/meshes/`` (nothing downloaded; the output is byte-for-byte the
same on every run, which ``tests/scene/test_objects_mesh.py`` checks).

    python scripts/make_meshes.py            # (re)write scenes/meshes/bunny.obj
    python scripts/make_meshes.py --check    # exit 1 if the committed files differ from what this makes

``bunny.obj``: a "bunny-like" blob, an icosphere (4 subdivisions: 2562 vertices, 5120 triangles) displaced
radially: an ellipsoidal body, a head, two long ears and a tail, each a smooth bump in the direction it points
to (r = body(u) + Σ a·exp(−(1 − u·d)/w)). Star-shaped around its centre, hence closed and free of
self-intersections; about 170 KB of OBJ text (positions to 5 decimals, faces counter-clockwise from outside).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "scenes" / "meshes"

#: (direction, amplitude, width) of the bumps on the body: head, two ears, tail
BUMPS = [
    ((0.75, 0.55, 0.0), 0.55, 0.08),
    ((0.3, 0.9, 0.3), 0.7, 0.035),
    ((0.3, 0.9, -0.3), 0.7, 0.035),
    ((-0.97, 0.25, 0.0), 0.25, 0.03),
]


def bunny() -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and faces (F, 3) of the bunny-like blob (not yet to unit size: study scales it)."""
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=4)
    u = np.asarray(m.vertices, float)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    r = 1.0 / np.sqrt((u[:, 0] / 1.0) ** 2 + (u[:, 1] / 0.75) ** 2 + (u[:, 2] / 0.7) ** 2)  # the body
    for d, a, w in BUMPS:
        d = np.asarray(d) / np.linalg.norm(d)
        r += a * np.exp(-(1 - u @ d) / w)
    return u * r[:, None], np.asarray(m.faces)


def obj_text(V: np.ndarray, F: np.ndarray, name: str) -> str:
    lines = [f"# {name}: made by scripts/make_meshes.py", f"o {name}"]
    lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in V]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in F]
    return "\n".join(lines).replace("-0.00000", "0.00000") + "\n"


def files() -> dict[str, str]:
    """File name → text of every shipped mesh."""
    return {"bunny.obj": obj_text(*bunny(), "bunny")}


if __name__ == "__main__":
    made = files()
    if "--check" in sys.argv:
        sys.exit(0 if all((OUT / n).is_file() and (OUT / n).read_text() == t for n, t in made.items()) else 1)
    OUT.mkdir(parents=True, exist_ok=True)
    for name, text in made.items():
        (OUT / name).write_text(text)
        print(f"wrote {OUT / name} ({len(text.encode()) / 1024:.0f} KiB)")
