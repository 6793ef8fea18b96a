"""The walkthrough renderer: a bake drawn through a moderngl context it is
given (a window's or a headless one); it never opens a window itself and
never imports glfw (docs/design.md section 9).

One vertex buffer holds the baked triangles (position, TEXCOORD_0,
TEXCOORD_1); the bake's triangles come sorted by (material, page), so one
draw per such group. The lightmap pages are one float texture array
(half floats, as the file stores them), sampled bilinearly (bicubic on
request); albedo textures are float textures, repeated, bilinear.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import perspective, view_of

MODES = ("lightmap", "irradiance", "albedo", "checker", "pages")  # u_mode 0..4


@dataclass(frozen=True)
class Draw:
    first: int      # first vertex
    count: int      # vertices
    material: int
    page: int


def draw_groups(bake) -> list:
    """Runs of consecutive triangles with one (material, page)."""
    mat, page = bake.scene.material_ids, bake.page
    if len(mat) == 0:
        return []
    change = np.nonzero((np.diff(mat) != 0) | (np.diff(page) != 0))[0] + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [len(mat)]])
    return [Draw(int(3 * a), int(3 * (b - a)), int(mat[a]), int(page[a])) for a, b in zip(starts, ends)]


class Renderer:
    """Draws a bake: `render(camera, width, height, ...)` into the bound
    framebuffer."""

    def __init__(self, ctx, bake):
        from .context import build_program
        self.ctx = ctx
        self.bake = bake
        scene = bake.scene
        self.program = build_program(ctx, "lightmap.vert", "lightmap.frag")
        n = len(scene.vertices)
        uv0 = scene.uvs if scene.uvs is not None else np.zeros((n, 2), np.float32)
        data = np.concatenate([scene.vertices, uv0, bake.uv1.reshape(-1, 2)], axis=1)
        self.vbo = ctx.buffer(np.ascontiguousarray(data, np.float32).tobytes())
        if "in_uv0" in self.program:
            layout = (self.vbo, "3f 2f 2f", "in_position", "in_uv0", "in_uv1")
        else:  # no textured material: the compiler dropped the texture coordinates
            layout = (self.vbo, "3f 8x 2f", "in_position", "in_uv1")
        self.vao = ctx.vertex_array(self.program, [layout])
        pages = np.ascontiguousarray(bake.pages, np.float16)
        p, size = pages.shape[0], pages.shape[1]
        self.pages = ctx.texture_array((size, size, p), 3, pages.tobytes(), dtype="f2")
        self.pages.repeat_x = self.pages.repeat_y = False
        import moderngl
        self.pages.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.textures = {}
        for i, m in enumerate(scene.materials):
            if m.texture is not None and scene.uvs is not None:
                t = np.ascontiguousarray(m.texture, np.float32)
                tex = ctx.texture((t.shape[1], t.shape[0]), 3, t.tobytes(), dtype="f4")
                tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
                self.textures[i] = tex
        self.draws = draw_groups(bake)
        lo, hi = scene.bounds()
        self.extent = float(np.linalg.norm(hi - lo)) or 1.0

    def clip_range(self, camera):
        """Near and far planes around the scene's bounds."""
        return self.extent * 1e-4, self.extent * 4.0

    def render(self, camera, width, height, mode="lightmap", exposure=1.0, tonemap=True, bicubic=False):
        """Draws the bake seen by `camera` (a scene Camera or FlyCamera)
        into the bound framebuffer (viewport width x height)."""
        import moderngl
        ctx = self.ctx
        near, far = self.clip_range(camera)
        vp = perspective(camera.yfov, width / height, near, far) @ view_of(camera)
        ctx.viewport = (0, 0, width, height)
        ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.front_face = "ccw"
        ctx.cull_face = "back"
        prog = self.program
        prog["u_view_proj"].write(vp.T.astype(np.float32).tobytes())
        prog["u_mode"].value = MODES.index(mode)
        prog["u_exposure"].value = float(exposure)
        prog["u_tonemap"].value = bool(tonemap)
        prog["u_bicubic"].value = bool(bicubic)
        self.pages.use(0)
        prog["u_pages"].value = 0
        if "u_texture" in prog:
            prog["u_texture"].value = 1
        mats = self.bake.scene.materials
        for d in self.draws:
            m = mats[d.material]
            prog["u_albedo"].value = tuple(float(v) for v in m.albedo)
            prog["u_emission"].value = tuple(float(v) for v in m.emission)
            prog["u_page"].value = d.page
            tex = self.textures.get(d.material)
            prog["u_has_texture"].value = tex is not None
            if tex is not None:
                tex.use(1)
            self.vao.render(moderngl.TRIANGLES, vertices=d.count, first=d.first)

    def release(self):
        for obj in (self.vao, self.vbo, self.pages, self.program, *self.textures.values()):
            obj.release()
