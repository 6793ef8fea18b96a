"""Cameras a user did not put in the file: an automatic one that sees the
scene (from outside an object, through the open side of a box, from inside
a closed room), and one set on the command line (look-from, look-at)."""
from __future__ import annotations

import numpy as np

from ..errors import SceneError
from .model import Camera, Scene, make_camera

OPEN_SIDE = 0.5          # a side of the bounds is open when half the rays from the centre through it escape
SIDE_RAYS = 9            # rays per side: a 9 x 9 grid over the face
ROOM_FOV = np.radians(70.0)
OBJECT_FOV = np.radians(45.0)


def _face_rays(centre, lo, hi, axis, sign):
    """Unit directions from `centre` to a grid of points just past the face
    of the bounds (axis, sign), and the distances to those points."""
    g = (np.arange(SIDE_RAYS) + 0.5) / SIDE_RAYS
    a1, a2 = (axis + 1) % 3, (axis + 2) % 3
    u, v = np.meshgrid(g, g, indexing="ij")
    pts = np.empty((u.size, 3))
    margin = 0.01 * (hi[axis] - lo[axis]) + 1e-9 * max(abs(lo[axis]), abs(hi[axis]), 1.0)  # past a wall on the face
    pts[:, axis] = hi[axis] + margin if sign > 0 else lo[axis] - margin
    pts[:, a1] = lo[a1] + u.ravel() * (hi[a1] - lo[a1])
    pts[:, a2] = lo[a2] + v.ravel() * (hi[a2] - lo[a2])
    d = pts - centre
    dist = np.linalg.norm(d, axis=1)
    return d / dist[:, None], dist


def _escape_fraction(bvh, centre, lo, hi, axis, sign):
    """Share of the rays from `centre` to a grid of points on the face of the
    bounds (axis, sign) that reach it without a hit."""
    d, dist = _face_rays(centre, lo, hi, axis, sign)
    t, tri, _, _ = bvh.closest(np.broadcast_to(centre, d.shape), d, 0.0, dist)
    return float(np.mean(tri < 0))


def encloses_centre_from_inside(scene: Scene, bvh, centre, lo, hi) -> bool:
    """Is the closed surface around the bounds' centre a body the centre
    lies inside (a scan, a closed box seen from outside) rather than a room?

    A room's walls face its inside: rays from the centre meet their front
    faces. A closed body's surface faces away from its inside: rays from a
    point within meet its back faces (a scan read two-sided keeps its
    winding). Where the winding says nothing clear (under two thirds of
    the hits agree), the distances decide: a room's walls lie on the
    bounds, a body enclosing the centre mostly well inside them.
    """
    dirs, dists = [], []
    for axis in range(3):
        for sign in (-1, 1):
            d, dist = _face_rays(centre, lo, hi, axis, sign)
            dirs.append(d)
            dists.append(dist)
    d, dist = np.concatenate(dirs), np.concatenate(dists)
    t, tri, _, _ = bvh.closest(np.broadcast_to(centre, d.shape), d, 0.0, dist)
    hit = tri >= 0
    if not hit.any():
        return False
    c = scene.vertices[scene.triangles[tri[hit]]].astype(np.float64)
    normal = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    back = float(np.mean(np.einsum("ij,ij->i", normal, d[hit]) > 0))
    if back >= 2 / 3:
        return True
    if back <= 1 / 3:
        return False
    return float(np.median(t[hit] / dist[hit])) < 0.75


def camera_for(scene: Scene, which=None, bvh=None) -> Camera:
    """A camera of the scene by name or index (None: its first, or an
    automatic one that sees the scene; `bvh` spares that a build)."""
    if which is None:
        if scene.cameras:
            return scene.cameras[0]
        return auto_camera(scene, bvh)
    if isinstance(which, int) or (isinstance(which, str) and which.lstrip("-").isdigit()):
        i = int(which)
        if not -len(scene.cameras) <= i < len(scene.cameras):
            raise SceneError(f"camera index {i} out of range ({len(scene.cameras)} cameras)", scene.path)
        return scene.cameras[i]
    for cam in scene.cameras:
        if cam.name == which:
            return cam
    names = ", ".join(c.name for c in scene.cameras) or "none"
    raise SceneError(f"no camera named {which!r} (cameras: {names})", scene.path)


def auto_camera(scene: Scene, bvh=None) -> Camera:
    """A camera that sees the scene's surfaces when the file has none:

    - an object (every side of its bounds open): from outside, in front
      (-Z) and a little above, framing the bounds;
    - a box with an open side (the classic Cornell box OBJ has no front
      wall): outside that side, looking in through it, framing the side;
    - a closed body around the bounds' centre (a scanned statue, a closed
      box): from outside, as an object (`encloses_centre_from_inside`);
    - a closed room: inside, at the centre of the bounds pulled back from
      the far wall, looking at it along the longest free horizontal line.
    """
    from .bvh import build_scene_bvh
    lo, hi = scene.bounds()
    centre = (lo + hi) / 2
    size = np.maximum(hi - lo, 1e-9 * max(float(np.abs(hi).max()), 1.0))
    bvh = bvh or build_scene_bvh(scene)
    sides = [(axis, sign) for axis in (2, 0, 1) for sign in (-1, 1)]  # front/back first, then sides, then top
    openness = {s: _escape_fraction(bvh, centre, lo, hi, *s) for s in sides}
    open_sides = [s for s in sides if openness[s] >= OPEN_SIDE]
    if len(open_sides) == len(sides) or not open_sides:
        if open_sides or encloses_centre_from_inside(scene, bvh, centre, lo, hi):  # an object: from outside
            d = np.array([0.0, 0.3, -1.0]) / np.linalg.norm([0.0, 0.3, -1.0])
            pos = centre + d * _framing_distance(scene.vertices, centre, d, OBJECT_FOV)
            return make_camera("auto", pos, centre - pos, (0, 1, 0), OBJECT_FOV)
        return _room_camera(bvh, centre, size)
    axis, sign = max(open_sides, key=lambda s: (openness[s], s[0] != 1))  # prefer a wall to the ceiling
    a1, a2 = (axis + 1) % 3, (axis + 2) % 3
    half = 0.5 * max(size[a1], size[a2])
    face = centre.copy()
    face[axis] = hi[axis] if sign > 0 else lo[axis]
    out = np.zeros(3)
    out[axis] = sign
    pos = face + out * (half / np.tan(OBJECT_FOV / 2))
    up = (0, 0, 1) if axis == 1 else (0, 1, 0)
    return make_camera("auto", pos, -out, up, OBJECT_FOV)


def _framing_distance(vertices, centre, towards, fov, margin=1.15) -> float:
    """The distance from `centre` along `towards` (unit) at which a camera
    looking back at the centre, with a square field of view `fov`, sees
    every vertex: vertex v at lateral offset l and depth z past the centre
    needs l <= tan(fov / 2) (D + z)."""
    rel = np.asarray(vertices, np.float64) - centre
    depth = -rel @ towards  # how far beyond the centre, seen from the camera
    up = np.array([0.0, 1.0, 0.0]) - towards[1] * towards
    up /= np.linalg.norm(up)
    right = np.cross(towards, up)
    lateral = np.maximum(np.abs(rel @ up), np.abs(rel @ right))
    need = lateral / np.tan(fov / 2) - depth
    return margin * max(float(need.max()), 1e-9)


def _room_camera(bvh, centre, size):
    """Inside a closed room: look along the horizontal direction with the
    most free space, from 80% of the way back to the wall behind."""
    ang = np.radians(np.arange(0, 360, 15))
    dirs = np.stack([np.sin(ang), np.zeros_like(ang), np.cos(ang)], axis=1)
    far = 4 * float(np.linalg.norm(size))
    t, _, _, _ = bvh.closest(np.broadcast_to(centre, dirs.shape), dirs, 0.0, np.full(len(dirs), far))
    t = np.minimum(t, far)
    k = int(np.argmax(t))
    forward = dirs[k]
    back = float(t[(k + len(dirs) // 2) % len(dirs)])
    pos = centre - forward * 0.8 * back
    return make_camera("auto", pos, forward, (0, 1, 0), ROOM_FOV)


def adjust_camera(camera: Camera, look_from=None, look_at=None, up=None, fov_deg=None) -> Camera:
    """`camera` with what the command line set replaced: position
    (look_from), target (look_at; default: straight ahead as before),
    up vector and vertical field of view in degrees."""
    pos = np.asarray(look_from, float) if look_from is not None else camera.position
    if look_at is not None:
        forward = np.asarray(look_at, float) - pos
        if np.linalg.norm(forward) == 0:
            from ..errors import SceneError
            raise SceneError("--look-at is the camera's own position")
    else:
        forward = camera.forward
    yfov = np.radians(fov_deg) if fov_deg is not None else camera.yfov
    name = camera.name if look_from is None and look_at is None else "command line"
    return make_camera(name, pos, forward, camera.up if up is None else up, yfov, camera.aspect)
