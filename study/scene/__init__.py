"""What is rendered: the one scene description (schema and validation), the environment behind one interface — the box
room, a mesh file or a Mitsuba scene as triangles with their materials and lights (``sources``: one file per source
type, registered by name; ``environment``, ``room``; mesh files read by ``obj``, ``gltf`` and ``meshfile`` into
``parts``, their referenced files keyed by ``references``), placement checks by ray casting with Embree
(``placement``) and automatic placement of the keys a scene leaves out (``autoplace``) — the camera's rays, and the
shaded object (sphere or mesh) as geometry.

Owns: :class:`Scene` (``schema``), :class:`RoomMesh` (``room``), :func:`camera_rays` (``camera``), object meshes and
their exact ray queries (``objects``). Imports nothing of study but the bottom modules (errors, io, validation,
progress; runtime to load Mitsuba scenes); embreex directly for placement's rays.
"""

from study.scene.camera import camera_rays, look_at_basis
from study.scene.room import SURFACES, RoomMesh, room_mesh, texture
from study.scene.schema import Camera, Column, Scene, Sphere, Vec3, load_scene_file, scene_from_dict

__all__ = [
    "Camera",
    "Column",
    "RoomMesh",
    "SURFACES",
    "Scene",
    "Sphere",
    "Vec3",
    "camera_rays",
    "load_scene_file",
    "look_at_basis",
    "room_mesh",
    "scene_from_dict",
    "texture",
]
