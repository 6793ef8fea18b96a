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

from baker.scene.surfaces import VOXEL_PASS

from .camera import perspective, view_of

MODES = ("lightmap", "irradiance", "albedo", "checker", "pages")  # the shader's MODE 0..4
ATTRIBUTES = {"in_position": ("3f", "12x"), "in_uv0": ("2f", "8x"), "in_uv1": ("2f", "8x")}  # read, skipped


@dataclass(frozen=True)
class Draw:
    first: int      # first vertex
    count: int      # vertices
    material: int
    page: int


def material_texture(ctx, m):
    """A material's albedo texture on the GPU: RGBA, the albedo and the
    mask's alpha (1 where the material is not masked); a mask is tested at
    the nearest texel, as every ray of the bake tested it."""
    import moderngl
    t = np.ones(m.texture.shape[:2] + (4,), np.float32)
    t[..., :3] = m.texture
    if m.masked and m.opacity is not None and m.opacity.shape == m.texture.shape[:2]:
        t[..., 3] = m.opacity
    tex = ctx.texture((t.shape[1], t.shape[0]), 4, t.tobytes(), dtype="f4")
    f = moderngl.NEAREST if m.masked else moderngl.LINEAR
    tex.filter = (f, f)
    return tex


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

    def __init__(self, ctx, bake, interactive=False):
        self.ctx = ctx
        self.bake = bake
        scene = bake.scene
        n = len(scene.vertices)
        uv0 = scene.uvs if scene.uvs is not None else np.zeros((n, 2), np.float32)
        data = np.concatenate([scene.vertices, uv0, bake.uv1.reshape(-1, 2)], axis=1)
        self.vbo = ctx.buffer(np.ascontiguousarray(data, np.float32).tobytes())
        self.variants = {}  # (mode, bicubic, tonemap, textured, glass, emit texture) -> (program, vertex array)
        pages = np.ascontiguousarray(bake.pages, np.float16)
        p, size = pages.shape[0], pages.shape[1]
        self.pages = ctx.texture_array((size, size, p), 3, pages.tobytes(), dtype="f2")
        self.pages.repeat_x = self.pages.repeat_y = False
        import moderngl
        self.pages.filter = (moderngl.LINEAR, moderngl.LINEAR)
        self.textures = {}
        for i, m in enumerate(scene.materials):
            if m.texture is not None and scene.uvs is not None:
                self.textures[i] = material_texture(ctx, m)
        self.emit_textures = {}
        for i, m in enumerate(scene.materials):
            if m.emission_texture is not None and scene.uvs is not None and float(np.max(m.emission)) > 0:
                t = np.ascontiguousarray(m.emission_texture, np.float32)
                tex = ctx.texture((t.shape[1], t.shape[0]), 3, t.tobytes(), dtype="f4")
                tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
                self.emit_textures[i] = tex
        self.draws = draw_groups(bake)
        self.probe_objects = None   # objects.ProbeObjects, made when an object is first drawn
        self.interactive = interactive   # the window (objects move between frames), not a snapshot
        self._prepared = None
        self.probe_view = None      # objects.ProbeGridView, made when the probes are first shown
        self.dynamic = None         # objects.DynamicMeshes, made when the bake's dynamic meshes are first drawn
        self.sky_programs = {}   # tonemap -> (program, vertex array): the sky the bake was lit by, if any
        lo, hi = scene.bounds()
        self.extent = float(np.linalg.norm(hi - lo)) or 1.0

    def prepared(self):
        """The bake's scene prepared (its BVH for the moving objects' rays),
        made once, on first use."""
        if self._prepared is None:
            from baker.scene.prepared import prepare
            self._prepared = prepare(self.bake.scene)
        return self._prepared

    def variant(self, mode, bicubic, tonemap, textured=False, glass=False, emit_texture=False):
        """The program (and its vertex array) of one view, built on first use."""
        key = (MODES.index(mode), bool(bicubic), bool(tonemap), bool(textured), bool(glass), bool(emit_texture))
        if key not in self.variants:
            from .context import build_program
            prog = build_program(self.ctx, "lightmap.vert", "lightmap.frag",
                                 {"MODE": key[0], "BICUBIC": key[1], "TONEMAP": key[2], "TEXTURED": key[3],
                                  "GLASS": key[4], "EMIT_TEXTURE": key[5]})
            names = [a for a in ATTRIBUTES if a in prog]  # a view may not read every attribute: skip its bytes
            fmt = " ".join(ATTRIBUTES[a][0 if a in names else 1] for a in ATTRIBUTES)
            self.variants[key] = (prog, self.ctx.vertex_array(prog, [(self.vbo, fmt, *names)]))
        return self.variants[key]

    def draw_sky(self, vp, tonemap, exposure):
        """The bake's sky (if it was lit by one) at the far plane, drawn
        after the surfaces and before the glass: where no surface is, or
        through glass, it shows, as in the path tracer."""
        sky = self.bake.scene.sky
        if sky is None:
            return
        import moderngl
        from baker.scene.model import UP
        if tonemap not in self.sky_programs:
            from .context import build_program
            prog = build_program(self.ctx, "sky.vert", "sky.frag", {"TONEMAP": tonemap})
            self.sky_programs[tonemap] = (prog, self.ctx.vertex_array(prog, []))
        prog, vao = self.sky_programs[tonemap]
        prog["u_inv_view_proj"].write(np.linalg.inv(vp).T.astype(np.float32).tobytes())
        prog["u_sky"].value = tuple(float(v) for v in sky.radiance)
        prog["u_up"].value = tuple(float(v) for v in UP)
        prog["u_hemisphere"].value = bool(sky.hemisphere)
        if "u_exposure" in prog:
            prog["u_exposure"].value = float(exposure)
        # at the far plane (depth 1, as cleared): it passes '<=' only where no surface was drawn
        self.ctx.depth_func = "<="
        self.ctx.fbo.depth_mask = False
        vao.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.fbo.depth_mask = True
        self.ctx.depth_func = "<"

    def clip_range(self, camera):
        """Near and far planes around the scene's bounds."""
        return self.extent * 1e-4, self.extent * 4.0

    def render(self, camera, width, height, mode="lightmap", exposure=1.0, tonemap=True, bicubic=False, objects=(),
               probes=False):
        """Draws the bake seen by `camera` (a scene Camera or FlyCamera)
        into the bound framebuffer (viewport width x height), with the
        moving `objects` (objects.Sphere) lit by its probes, and with
        `probes` the probes themselves (objects.ProbeGridView). In the
        lightmap view the bake's dynamic meshes are drawn lit by its probes
        too, where the file has them unless an objects.Placed in `objects`
        moves one."""
        import moderngl
        ctx = self.ctx
        near, far = self.clip_range(camera)
        vp = perspective(camera.yfov, width / height, near, far) @ view_of(camera)
        ctx.viewport = (0, 0, width, height)
        ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.front_face = "ccw"
        ctx.cull_face = "back"
        # nearest first, so that llvmpipe's early depth test skips the surfaces they hide: the moving
        # objects (in front of the camera as a rule: drawn after the scene, the scene behind them would
        # be shaded as well), then the scene, the sky where nothing is, and last the thin glass, which
        # tints whatever lies behind it (an object behind a pane too)
        self.draw_objects(vp, mode, tonemap, exposure, objects, probes)
        self.pages.use(0)
        mats = self.bake.scene.materials
        # thin glass the bake holds no light for (t >= VOXEL_PASS) goes last: it filters what lies behind it
        glass = [d for d in self.draws if mats[d.material].transmission >= VOXEL_PASS]
        opaque = [d for d in self.draws if mats[d.material].transmission < VOXEL_PASS]
        current = [None]

        def draw(d):
            m = mats[d.material]
            tex = self.textures.get(d.material)
            emits = d.material in self.emit_textures
            prog, vao = self.variant(mode, bicubic, tonemap, tex is not None, m.transmission >= VOXEL_PASS, emits)
            if prog is not current[0]:  # a program's shared settings once per switch
                current[0] = prog
                prog["u_view_proj"].write(vp.T.astype(np.float32).tobytes())
                for name, value in (("u_exposure", float(exposure)), ("u_pages", 0), ("u_texture", 1),
                                    ("u_emit_texture", 2)):
                    if name in prog:
                        prog[name].value = value
            for name, value in (("u_albedo", tuple(float((1.0 - m.transmission) * v) for v in m.albedo)),
                                ("u_emission", tuple(float(v) for v in m.emission)), ("u_page", d.page),
                                ("u_alpha", float(m.alpha)), ("u_cutoff", float(m.alpha_cutoff) if m.masked else -1.0),
                                ("u_glass", tuple(float(m.transmission * a) for a in m.albedo))):
                if name in prog:  # (a view may not read it)
                    prog[name].value = value
            if tex is not None:
                tex.use(1)
            if emits:
                self.emit_textures[d.material].use(2)
            vao.render(moderngl.TRIANGLES, vertices=d.count, first=d.first)

        for d in opaque:
            draw(d)
        if mode == "lightmap":
            self.draw_sky(vp, bool(tonemap), exposure)
        if glass:   # blended as dst * tint, writing no depth
            ctx.enable(moderngl.BLEND)
            ctx.blend_func = moderngl.ZERO, moderngl.SRC_COLOR
            ctx.fbo.depth_mask = False
            for d in glass:
                draw(d)
            ctx.disable(moderngl.BLEND)
            ctx.fbo.depth_mask = True

    def draw_objects(self, vp, mode, tonemap, exposure, objects, probes):
        """The moving spheres, the bake's dynamic meshes and the probe view
        (render's `objects` and `probes`)."""
        from .objects import Placed
        spheres = [o for o in objects if not isinstance(o, Placed)]
        if spheres:
            if self.probe_objects is None:
                from .objects import ProbeObjects
                self.probe_objects = ProbeObjects(self.ctx, self.bake, self.interactive, self.prepared())
            self.probe_objects.draw(vp, spheres, tonemap, exposure)
        if self.bake.scene.dynamic and self.bake.probes is not None and mode == "lightmap":
            if self.dynamic is None:
                from .objects import DynamicMeshes
                self.dynamic = DynamicMeshes(self.ctx, self.bake, self.prepared(), self.interactive)
            offsets = [(0.0, 0.0, 0.0)] * len(self.bake.scene.dynamic)
            for o in objects:
                if isinstance(o, Placed):
                    offsets[o.index] = o.offset
            self.dynamic.draw(vp, offsets, tonemap, exposure)
        if probes:
            if self.probe_view is None:
                from .objects import ProbeGridView
                self.probe_view = ProbeGridView(self.ctx, self.bake)
            self.probe_view.draw(vp, tonemap, exposure)

    def release(self):
        for view in (self.probe_objects, self.probe_view, self.dynamic):
            if view is not None:
                view.release()
        for prog, vao in (*self.variants.values(), *self.sky_programs.values()):
            vao.release()
            prog.release()
        for obj in (self.vbo, self.pages, *self.textures.values(), *self.emit_textures.values()):
            obj.release()
