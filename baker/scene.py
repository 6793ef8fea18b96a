"""The scene model (flat arrays) and its loaders: glTF 2.0, OBJ/MTL, PLY.

A `Scene` is what every later stage reads: triangles as indexed float32
vertices, one material index per triangle, materials as flat arrays
(albedo, emitted radiance, double-sidedness, optional albedo texture),
cameras and punctual lights. Units: emitted radiance L_e in W m^-2 sr^-1
(METHOD.md section 1); punctual intensity in W/sr, directional in W/m^2.
"""
from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field

import numpy as np

from .errors import SceneError, VoxgiWarning


@dataclass(frozen=True)
class Material:
    name: str
    albedo: np.ndarray            # (3,) float32, linear base colour factor
    emission: np.ndarray          # (3,) float32, emitted radiance L_e
    double_sided: bool = False
    texture: np.ndarray | None = None   # (h, w, 3) float32 linear albedo, multiplied by `albedo`


@dataclass(frozen=True)
class Camera:
    name: str
    position: np.ndarray          # (3,) float64
    forward: np.ndarray           # (3,) unit
    up: np.ndarray                # (3,) unit, orthogonal to forward
    yfov: float                   # vertical field of view, radians
    aspect: float | None = None   # width / height, None: from the image


@dataclass(frozen=True)
class PunctualLight:
    name: str
    kind: str                     # 'point' | 'spot' | 'directional'
    intensity: np.ndarray         # (3,) W/sr (point, spot) or W/m^2 (directional), colour included
    position: np.ndarray          # (3,)
    direction: np.ndarray         # (3,) unit, where the light points
    inner_cone: float = 0.0       # radians (spot)
    outer_cone: float = np.pi / 4


@dataclass(frozen=True)
class Scene:
    """Triangles and what they are made of.

    vertices (nv, 3) float32; triangles (nt, 3) int32; material_ids (nt,) int32;
    normals (nv, 3) float32 or None; uvs (nv, 2) float32 or None.
    """
    vertices: np.ndarray
    triangles: np.ndarray
    material_ids: np.ndarray
    materials: tuple
    normals: np.ndarray | None = None
    uvs: np.ndarray | None = None
    cameras: tuple = ()
    lights: tuple = ()
    path: str = ""
    warnings: tuple = field(default=())

    # -- flat material arrays for kernels ----------------------------------
    @property
    def albedo(self) -> np.ndarray:
        """(nm, 3) float32 albedo factors."""
        return np.array([m.albedo for m in self.materials], np.float32).reshape(-1, 3)

    @property
    def emission(self) -> np.ndarray:
        """(nm, 3) float32 emitted radiance."""
        return np.array([m.emission for m in self.materials], np.float32).reshape(-1, 3)

    @property
    def double_sided(self) -> np.ndarray:
        """(nm,) bool."""
        return np.array([m.double_sided for m in self.materials], np.bool_)

    def triangle_corners(self) -> np.ndarray:
        """(nt, 3, 3) float64 corner positions."""
        return self.vertices[self.triangles].astype(np.float64)

    def triangle_areas(self) -> np.ndarray:
        c = self.triangle_corners()
        return 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)

    def emitter_triangles(self) -> np.ndarray:
        """Indices of triangles whose material emits."""
        return np.nonzero(self.emission.max(axis=1)[self.material_ids] > 0)[0].astype(np.int32)

    def emitted_power(self) -> np.ndarray:
        """(3,) total power of the area emitters, W: pi L_e area per emitting side."""
        em = self.emission[self.material_ids].astype(np.float64)
        sides = np.where(self.double_sided[self.material_ids], 2.0, 1.0)
        return (np.pi * em * (self.triangle_areas() * sides)[:, None]).sum(axis=0)

    def bounds(self):
        return self.vertices.min(axis=0).astype(np.float64), self.vertices.max(axis=0).astype(np.float64)

    def camera(self, which=None) -> Camera:
        """A camera by name or index (None: the first, or one framing the bounds)."""
        if which is None:
            return self.cameras[0] if self.cameras else default_camera(self)
        if isinstance(which, int) or (isinstance(which, str) and which.lstrip("-").isdigit()):
            i = int(which)
            if not -len(self.cameras) <= i < len(self.cameras):
                raise SceneError(f"camera index {i} out of range ({len(self.cameras)} cameras)", self.path)
            return self.cameras[i]
        for cam in self.cameras:
            if cam.name == which:
                return cam
        names = ", ".join(c.name for c in self.cameras) or "none"
        raise SceneError(f"no camera named {which!r} (cameras: {names})", self.path)


def default_camera(scene: Scene) -> Camera:
    lo, hi = scene.bounds()
    c = (lo + hi) / 2
    r = float(np.linalg.norm(hi - lo)) / 2 or 1.0
    pos = c + np.array([0.0, 0.3, -1.0]) / np.linalg.norm([0.0, 0.3, -1.0]) * r * 2.5
    f = (c - pos) / np.linalg.norm(c - pos)
    return make_camera("auto", pos, f, (0, 1, 0), np.radians(45.0))


def make_camera(name, position, forward, up, yfov, aspect=None) -> Camera:
    f = np.asarray(forward, float)
    f = f / np.linalg.norm(f)
    u = np.asarray(up, float)
    r = np.cross(f, u)
    if np.linalg.norm(r) < 1e-9:
        r = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 0.0, 1.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    return Camera(name, np.asarray(position, float), f, u, float(yfov), aspect)


# ---------------------------------------------------------------------------
# Loading


def load_scene(path, one_sided=False) -> Scene:
    """Loads a .gltf/.glb, .obj or .ply file into a validated `Scene`.

    OBJ and PLY carry no sidedness: they are double-sided unless `one_sided`.
    Raises SceneError naming the file and the problem.
    """
    path = os.fspath(path)
    if not os.path.exists(path):
        raise SceneError("file not found", path)
    if os.path.isdir(path):
        raise SceneError("is a folder, not a scene file", path)
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext in (".gltf", ".glb"):
            from .gltf_read import read_gltf
            parts = read_gltf(path)
        elif ext == ".obj":
            parts = _read_obj(path, not one_sided)
        elif ext == ".ply":
            parts = _read_ply(path, not one_sided)
        else:
            raise SceneError(f"unsupported format {ext or '(no extension)'!r}; use .glb, .gltf, .obj or .ply", path)
    except SceneError as e:
        if e.path is None:
            e.path = path
        raise
    except Exception as e:  # a parser's own exception: say which file, in one line
        raise SceneError(f"cannot read ({type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''})",
                         path) from e
    return _validate(path, **parts)


def _validate(path, vertices, triangles, material_ids, materials, normals=None, uvs=None, cameras=(),
              lights=()) -> Scene:
    vertices = np.asarray(vertices, np.float64).reshape(-1, 3)
    triangles = np.asarray(triangles, np.int64).reshape(-1, 3)
    material_ids = np.asarray(material_ids, np.int64).reshape(-1)
    notes = []
    if len(triangles) == 0:
        raise SceneError("no triangles", path)
    if not np.isfinite(vertices).all():
        bad = int((~np.isfinite(vertices)).any(axis=1).sum())
        raise SceneError(f"{bad} vertices are NaN or infinite", path)
    if triangles.min() < 0 or triangles.max() >= len(vertices):
        raise SceneError(f"triangle indices out of range (0..{len(vertices) - 1}, found "
                         f"{triangles.min()}..{triangles.max()})", path)
    if np.abs(vertices).max() > 1e18:
        raise SceneError("vertex coordinates beyond 1e18", path)
    c = vertices[triangles]
    area2 = np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1)
    scale = float(np.abs(vertices).max()) or 1.0
    # Below float32's resolution at this scale a triangle has no usable area.
    degenerate = area2 <= 1e-14 * scale * scale
    if degenerate.any():
        n = int(degenerate.sum())
        msg = f"{path}: dropped {n} degenerate (zero-area) triangle{'s' * (n != 1)}"
        notes.append(msg)
        warnings.warn(msg, VoxgiWarning, stacklevel=3)
        triangles, material_ids = triangles[~degenerate], material_ids[~degenerate]
        if len(triangles) == 0:
            raise SceneError("every triangle is degenerate", path)
    scene = Scene(vertices=vertices.astype(np.float32), triangles=triangles.astype(np.int32),
                  material_ids=material_ids.astype(np.int32), materials=tuple(materials),
                  normals=None if normals is None else np.asarray(normals, np.float32),
                  uvs=None if uvs is None else np.asarray(uvs, np.float32),
                  cameras=tuple(cameras), lights=tuple(lights), path=path, warnings=tuple(notes))
    if not len(scene.emitter_triangles()) and not scene.lights:
        msg = f"{path}: the scene has no emitter (no emissive material, no punctual light): it will bake black"
        warnings.warn(msg, VoxgiWarning, stacklevel=3)
        scene = Scene(**{**scene.__dict__, "warnings": scene.warnings + (msg,)})
    return scene


def _mat(name, albedo=(0.8, 0.8, 0.8), emission=(0, 0, 0), double_sided=False, texture=None) -> Material:
    return Material(name, np.asarray(albedo, np.float32)[:3], np.asarray(emission, np.float32)[:3],
                    bool(double_sided), texture)


def _srgb_to_linear(img: np.ndarray) -> np.ndarray:
    return np.where(img <= 0.04045, img / 12.92, ((img + 0.055) / 1.055) ** 2.4).astype(np.float32)


def _image_to_albedo(img) -> np.ndarray:
    """PIL image (sRGB) -> (h, w, 3) float32 linear."""
    arr = np.asarray(img.convert("RGB"), np.float32) / 255.0
    return _srgb_to_linear(arr)


def _parse_mtl(path):
    """name -> dict(Kd, Ke, map_Kd) from an MTL file (what trimesh drops: Ke)."""
    out, cur = {}, None
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            tok = line.split()
            if not tok:
                continue
            if tok[0] == "newmtl":
                cur = out.setdefault(" ".join(tok[1:]), {})
            elif cur is not None and tok[0] in ("Kd", "Ke") and len(tok) >= 4:
                cur[tok[0]] = [float(v) for v in tok[1:4]]
            elif cur is not None and tok[0] == "map_Kd":
                cur["map_Kd"] = tok[-1]
    return out


def _read_obj(path, double_sided):
    import trimesh
    from PIL import Image
    mtl = {}
    folder = os.path.dirname(path)
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.startswith("mtllib"):
                lib = os.path.join(folder, line.split(None, 1)[1].strip())
                if os.path.exists(lib):
                    mtl.update(_parse_mtl(lib))
    loaded = trimesh.load(path, force="scene", process=False, group_material=True)
    verts, tris, mids, uvs_all, materials, index = [], [], [], [], [], {}
    offset, any_uv = 0, False
    for node in loaded.graph.nodes_geometry:
        transform, gname = loaded.graph[node]
        geom = loaded.geometry[gname]
        if not hasattr(geom, "faces") or len(geom.faces) == 0:
            continue
        mat = getattr(getattr(geom, "visual", None), "material", None)
        mname = getattr(mat, "name", None) or "default"
        if mname not in index:
            d = mtl.get(mname, {})
            tex = None
            if "map_Kd" in d and os.path.exists(os.path.join(folder, d["map_Kd"])):
                tex = _image_to_albedo(Image.open(os.path.join(folder, d["map_Kd"])))
            index[mname] = len(materials)
            materials.append(_mat(mname, d.get("Kd", (0.8, 0.8, 0.8)), d.get("Ke", (0, 0, 0)), double_sided, tex))
        v = np.asarray(geom.vertices, np.float64)
        v = v @ transform[:3, :3].T + transform[:3, 3]
        verts.append(v)
        tris.append(np.asarray(geom.faces, np.int64) + offset)
        mids.append(np.full(len(geom.faces), index[mname]))
        uv = getattr(geom.visual, "uv", None)
        any_uv |= uv is not None and len(uv) == len(v)
        uvs_all.append(np.asarray(uv, np.float32) if uv is not None and len(uv) == len(v)
                       else np.zeros((len(v), 2), np.float32))
        offset += len(v)
    if not verts:
        raise SceneError("no triangles", path)
    return dict(vertices=np.concatenate(verts), triangles=np.concatenate(tris), material_ids=np.concatenate(mids),
                materials=materials, uvs=np.concatenate(uvs_all) if any_uv else None)


def _read_ply(path, double_sided):
    import trimesh
    mesh = trimesh.load(path, force="mesh", process=False)
    if not hasattr(mesh, "faces") or len(mesh.faces) == 0:
        raise SceneError("no triangles (a point cloud?)", path)
    return dict(vertices=np.asarray(mesh.vertices), triangles=np.asarray(mesh.faces),
                material_ids=np.zeros(len(mesh.faces)), materials=[_mat("default", double_sided=double_sided)])
