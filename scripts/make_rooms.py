"""Make the mesh-file environments that ship with study (nothing is downloaded):

* ``scenes/rooms/l_room.ply`` — an L-shaped room (two 3 m wide arms, 6 m long, 2.8 m high), one colour per face
  (PLY face colours): a non-convex interior where each arm hides part of the other from a reference point;
* ``scenes/rooms/atrium.obj`` (+ ``atrium.mtl``, ``atrium_floor.png``) — a 7 m × 7 m hall, 4.5 m high, with a
  square arcade of eight pillars joined by round arches, materials by colour (MTL ``Kd``) and a textured floor
  (``map_Kd``): the arches' undersides and the pillars' backs are hidden from the hall's centre.

* ``scenes/rooms/attic.ply`` — an attic under a roof of unequal slopes (6 m × 4 m floor, 1 m knee walls, the
  ridge 3.2 m high and 2 m from one side: slopes of 48° and 29°), one colour per face: a convex room that is not a
  box, with sloped ceilings the reference point sees obliquely.

Every face's normal points into free space (walls inward, pillars and arches outward), as study's placement
checks expect. Run: ``python scripts/make_rooms.py`` (deterministic; the files are committed).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "scenes" / "rooms"


# ---------------------------------------------------------------------------------------------- building blocks
def quad(p0, du, dv):
    """Two triangles of the quad p0, p0+du, p0+du+dv, p0+dv; normal du × dv."""
    p0, du, dv = map(np.asarray, (p0, du, dv))
    return [np.array([p0, p0 + du, p0 + du + dv]), np.array([p0, p0 + du + dv, p0 + dv])]


def box(lo, hi, *, inward=False, bottom=True):
    """The faces of a box, normals outward (or inward)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    ex, ey, ez = np.diag(hi - lo)
    faces = {
        "-y": quad(lo, ex, ez),
        "+y": quad(lo + ey, ez, ex),
        "-x": quad(lo, ez, ey),
        "+x": quad(lo + ex, ey, ez),
        "-z": quad(lo, ey, ex),
        "+z": quad(lo + ez, ex, ey),
    }
    if not bottom:
        del faces["-y"]
    tris = {k: v for k, v in faces.items()}
    if inward:
        tris = {k: [t[::-1] for t in v] for k, v in tris.items()}
    return tris


def polygon_fan(points, y, up: bool):
    """Triangles of a convex polygon at height y, normal +y (up) or −y."""
    p = [np.array([x, y, z], float) for x, z in points]
    tris = [np.array([p[0], p[i], p[i + 1]]) for i in range(1, len(p) - 1)]
    n = np.cross(tris[0][1] - tris[0][0], tris[0][2] - tris[0][0])
    if (n[1] > 0) != up:
        tris = [t[::-1] for t in tris]
    return tris


# ---------------------------------------------------------------------------------------------- L-shaped room
def l_room():
    """(triangles, rgb per triangle) of the L room: the L is [0,6]×[0,3] ∪ [0,3]×[0,6] in (x, z), height 2.8."""
    H = 2.8
    tris, cols = [], []

    def add(ts, rgb):
        tris.extend(ts)
        cols.extend([rgb] * len(ts))

    for rect, shade in (([(0, 0), (6, 0), (6, 3), (0, 3)], 0), ([(0, 3), (3, 3), (3, 6), (0, 6)], 1)):
        add(polygon_fan(rect, 0.0, up=True), (150, 120, 90) if shade else (170, 140, 100))  # floor
        add(polygon_fan(rect, H, up=False), (225, 225, 220))  # ceiling
    # walls: the outline walked counter-clockwise seen from above; each wall faces the inside
    outline = [(0, 0), (6, 0), (6, 3), (3, 3), (3, 6), (0, 6)]
    colours = [(190, 70, 60), (60, 110, 180), (220, 190, 70), (70, 160, 90), (150, 90, 170), (90, 170, 170)]
    for (a, b), rgb in zip(zip(outline, outline[1:] + outline[:1]), colours):
        p0 = np.array([a[0], 0.0, a[1]])
        du = np.array([b[0] - a[0], 0.0, b[1] - a[1]])
        ts = quad(p0, np.array([0.0, H, 0.0]), du)
        n = np.cross(ts[0][1] - ts[0][0], ts[0][2] - ts[0][0])
        probe = p0 + du / 2 + 0.01 * n / np.linalg.norm(n)
        inside = (0 < probe[0] < 6 and 0 < probe[2] < 3) or (0 < probe[0] < 3 and 0 < probe[2] < 6)
        add(ts if inside else [t[::-1] for t in ts], rgb)  # every wall faces the inside of the L
    return np.array(tris), np.array(cols, np.uint8)


# ---------------------------------------------------------------------------------------------- attic
def attic():
    """(triangles, rgb per triangle) of the attic: the cross-section (x, y) is the convex pentagon (0, 0), (6, 0),
    (6, 1), (2, 3.2), (0, 1), extruded along z over [0, 4]."""
    L, section = 4.0, [(0.0, 0.0), (6.0, 0.0), (6.0, 1.0), (2.0, 3.2), (0.0, 1.0)]
    centre = np.array([2.5, 1.2, 2.0])  # inside: every face is turned to face it
    colours = [(170, 140, 100), (60, 110, 180), (225, 215, 200), (200, 200, 225), (190, 70, 60)]
    tris, cols = [], []

    def add(ts, rgb):
        for t in ts:
            n = np.cross(t[1] - t[0], t[2] - t[0])
            tris.append(t if np.dot(n, centre - t[0]) > 0 else t[::-1])
            cols.append(rgb)

    for (a, b), rgb in zip(zip(section, section[1:] + section[:1]), colours):  # floor, knee wall, roofs, wall
        add(quad([a[0], a[1], 0.0], [b[0] - a[0], b[1] - a[1], 0.0], [0.0, 0.0, L]), rgb)
    for z, rgb in ((0.0, (70, 160, 90)), (L, (150, 90, 170))):  # the gable walls: fans of the pentagon
        p = [np.array([x, y, z]) for x, y in section]
        add([np.array([p[0], p[i], p[i + 1]]) for i in range(1, len(p) - 1)], rgb)
    return np.array(tris), np.array(cols, np.uint8)


def write_ply(path: Path, tris: np.ndarray, cols: np.ndarray) -> None:
    V = tris.reshape(-1, 3)
    lines = [
        "ply",
        "format ascii 1.0",
        f"element vertex {len(V)}",
        "property float x",
        "property float y",
        "property float z",
        f"element face {len(tris)}",
        "property list uchar int vertex_indices",
        "property uchar red",
        "property uchar green",
        "property uchar blue",
        "end_header",
    ]
    lines += [f"{x:.6g} {y:.6g} {z:.6g}" for x, y, z in V]
    lines += [f"3 {3 * i} {3 * i + 1} {3 * i + 2} {r} {g} {b}" for i, (r, g, b) in enumerate(cols)]
    path.write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------------------------------------- atrium
def arch(x0, x1, z, y0, thick, depth, n=12):
    """A round arch spanning x0..x1 (springing at height y0) in the plane z, ``thick`` high at its crown, ``depth``
    deep along z: n segments of a half ring, each a closed box-like prism with outward normals."""
    c, r_in = (x0 + x1) / 2, (x1 - x0) / 2
    r_out = r_in + thick
    tris = []
    for i in range(n):
        a0, a1 = np.pi * i / n, np.pi * (i + 1) / n
        pts = [
            np.array([c + r * np.cos(a), y0 + r * np.sin(a)])
            for r, a in ((r_in, a0), (r_in, a1), (r_out, a1), (r_out, a0))
        ]
        front = [np.array([p[0], p[1], z - depth / 2]) for p in pts]
        back = [np.array([p[0], p[1], z + depth / 2]) for p in pts]
        for k in range(4):  # the four sides of the segment
            a, b = k, (k + 1) % 4
            tris += [np.array([front[a], front[b], back[b]]), np.array([front[a], back[b], back[a]])]
        tris += [np.array([front[0], front[2], front[1]]), np.array([front[0], front[3], front[2]])]
        tris += [np.array([back[0], back[1], back[2]]), np.array([back[0], back[2], back[3]])]
    centre = np.array([c, y0 + r_in, z])
    out = []
    for t in tris:  # orient each face away from the ring's inside
        n = np.cross(t[1] - t[0], t[2] - t[0])
        m = t.mean(0)
        radial = np.array([m[0] - centre[0], m[1] - (y0), 0.0])
        ring_mid = np.array([c, y0, m[2]]) + (r_in + thick / 2) * radial / max(np.linalg.norm(radial), 1e-9)
        out.append(t if np.dot(n, m - ring_mid) >= 0 else t[::-1])
    return out


def atrium():
    """{material: triangles} of the atrium hall and its arcade."""
    S, H = 7.0, 4.5
    mats: dict[str, list] = {"floor": [], "walls": [], "ceiling": [], "stone": [], "arch": []}
    room = box((0, 0, 0), (S, H, S), inward=True)
    mats["floor"] += room["-y"]
    mats["ceiling"] += room["+y"]
    for k in ("-x", "+x", "-z", "+z"):
        mats["walls"] += room[k]
    w, h_p = 0.4, 2.2  # pillar width and height (arches spring there)
    xs = [1.5, 3.5, 5.5]
    for i, x in enumerate(xs):  # 8 pillars on the square's edge (no centre one)
        for j, z in enumerate(xs):
            if i == 1 and j == 1:
                continue
            for ts in box((x - w / 2, 0, z - w / 2), (x + w / 2, h_p, z + w / 2), bottom=False).values():
                mats["stone"] += ts
    for z in (1.5, 5.5):  # arches along x on the front and back rows
        for x0, x1 in zip(xs, xs[1:]):
            mats["arch"] += arch(x0 + w / 2, x1 - w / 2, z, h_p, 0.3, w)
    for x in (1.5, 5.5):  # and along z on the left and right rows
        for z0, z1 in zip(xs, xs[1:]):
            segs = arch(z0 + w / 2, z1 - w / 2, 0.0, h_p, 0.3, w)
            mats["arch"] += [t[:, [2, 1, 0]][::-1] + np.array([x, 0, 0]) for t in segs]  # swap x and z
    return mats


def write_obj(path: Path, mats: dict[str, list]) -> None:
    kd = {
        "floor": None,
        "walls": (0.75, 0.62, 0.45),
        "ceiling": (0.85, 0.85, 0.82),
        "stone": (0.55, 0.55, 0.6),
        "arch": (0.7, 0.35, 0.25),
    }
    mtl = []
    for name, c in kd.items():
        mtl += [f"newmtl {name}"]
        mtl += ["Kd 1 1 1", "map_Kd atrium_floor.png"] if c is None else [f"Kd {c[0]} {c[1]} {c[2]}"]
        mtl += [""]
    path.with_suffix(".mtl").write_text("\n".join(mtl))
    lines = ["# atrium: made by scripts/make_rooms.py", f"mtllib {path.with_suffix('.mtl').name}"]
    nv = nt = 0
    for name, tris in mats.items():
        lines.append(f"o {name}")
        lines.append(f"usemtl {name}")
        for t in tris:
            for v in t:
                lines.append(f"v {v[0]:.5f} {v[1]:.5f} {v[2]:.5f}")
            if name == "floor":  # texture coordinates: 1 tile per metre
                for v in t:
                    lines.append(f"vt {v[0] / 7:.5f} {v[2] / 7:.5f}")
                lines.append(f"f {nv + 1}/{nt + 1} {nv + 2}/{nt + 2} {nv + 3}/{nt + 3}")
                nt += 3
            else:
                lines.append(f"f {nv + 1} {nv + 2} {nv + 3}")
            nv += 3
    path.write_text("\n".join(lines) + "\n")


def floor_texture(path: Path, size: int = 256) -> None:
    """A 7 × 7 tile checker with grout, as an sRGB PNG."""
    from PIL import Image

    y, x = np.mgrid[0:size, 0:size] / size
    check = (np.floor(x * 7) + np.floor(y * 7)) % 2
    grout = (np.abs((x * 7) % 1 - 0.5) > 0.46) | (np.abs((y * 7) % 1 - 0.5) > 0.46)
    a, b = np.array([200, 185, 160]), np.array([90, 80, 75])
    img = np.where(grout[..., None], 40, a * (1 - check[..., None]) + b * check[..., None]).astype(np.uint8)
    Image.fromarray(img).save(path)


def main() -> int:
    OUT.mkdir(parents=True, exist_ok=True)
    write_ply(OUT / "l_room.ply", *l_room())
    write_ply(OUT / "attic.ply", *attic())
    write_obj(OUT / "atrium.obj", atrium())
    floor_texture(OUT / "atrium_floor.png")
    print("wrote", ", ".join(str(p.relative_to(OUT.parents[1])) for p in sorted(OUT.iterdir())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
