"""Progressive instant radiosity on the GPU (docs/design.md section 9): the
bake's ordered VPL list, `per_frame` VPLs a frame; each VPL renders the
distances around it into a cube (six faces side by side), then adds its
light, with the CPU's bounded near-field term, to a float accumulation
buffer at every pixel of a G-buffer of the view; the picture is the
running mean (emission and albedo applied once): it converges to the CPU's
instant radiosity over the same list (baker/render/instant_radiosity.py).
A camera move restarts it. The sky's directional VPLs use an orthographic
map of distances along their direction; the scene's punctual lights
(point, spot, sun) are added exactly once per restart, as the CPU adds
them to every frame.
"""
from __future__ import annotations

import math

import numpy as np

from baker.scene.model import LightKind

from .camera import look_at, perspective, view_of

FACES = [((1, 0, 0), (0, -1, 0)), ((-1, 0, 0), (0, -1, 0)), ((0, 1, 0), (0, 0, 1)), ((0, -1, 0), (0, 0, -1)),
         ((0, 0, 1), (0, -1, 0)), ((0, 0, -1), (0, -1, 0))]  # +x -x +y -y +z -z: forward and up


class Preview:
    """Accumulates VPLs for one camera and image size."""

    def __init__(self, ctx, renderer, camera, width, height, shadow_size=256, per_frame=16):
        import moderngl
        from .context import build_program
        bake = renderer.bake
        if bake.vpls is None or len(bake.vpls) == 0:
            from baker.errors import VoxgiError
            raise VoxgiError("this bake holds no VPL list for the preview (bake it again with this voxgi)")
        self.ctx, self.r, self.camera = ctx, renderer, camera
        self.size = (width, height)
        self.per_frame = per_frame
        self.vpls = bake.vpls
        self.lights = bake.scene.lights
        self.g_prog = build_program(ctx, "gbuffer.vert", "gbuffer.frag")
        self.s_prog = build_program(ctx, "shadow.vert", "shadow.frag")
        self.p_prog = build_program(ctx, "preview.vert", "preview.frag")
        self.g_vao = ctx.vertex_array(self.g_prog, [(renderer.vbo, "3f 2f 8x", "in_position", "in_uv0")])
        self.s_vao = ctx.vertex_array(self.s_prog, [(renderer.vbo, "3f 16x", "in_position")])
        self.p_vao = ctx.vertex_array(self.p_prog, [])
        w, h = width, height
        # the G-buffer, in gbuffer.frag's output order
        self.gtex = [ctx.texture((w, h), 4, dtype="f4") for _ in range(4)]
        self.g_position, self.g_normal, self.g_albedo, self.g_emission = self.gtex
        for t in self.gtex:
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.gdepth = ctx.depth_renderbuffer((w, h))
        self.gfbo = ctx.framebuffer(self.gtex, self.gdepth)
        self.shadow = ctx.texture((6 * shadow_size, shadow_size), 1, dtype="f4")
        self.shadow.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.sdepth = ctx.depth_renderbuffer((6 * shadow_size, shadow_size))
        self.sfbo = ctx.framebuffer([self.shadow], self.sdepth)
        self.shadow_size = shadow_size
        self.accum = ctx.texture((w, h), 4, dtype="f4")
        self.afbo = ctx.framebuffer([self.accum])
        self.punct = ctx.texture((w, h), 4, dtype="f4")
        self.pfbo = ctx.framebuffer([self.punct])
        lo, hi = bake.scene.bounds()
        self.extent = float(np.linalg.norm(hi - lo)) or 1.0
        self.used = 0
        self.frames = 0
        self._gbuffer()

    def _gbuffer(self):
        import moderngl
        ctx, (w, h) = self.ctx, self.size
        near, far = self.r.clip_range(self.camera)
        vp = perspective(self.camera.yfov, w / h, near, far) @ view_of(self.camera)
        self.gfbo.use()
        self.gfbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.viewport = (0, 0, w, h)
        ctx.enable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.g_prog["u_view_proj"].write(vp.T.astype(np.float32).tobytes())
        mats = self.r.bake.scene.materials
        for d in self.r.draws:
            m = mats[d.material]
            tex = self.r.textures.get(d.material)
            for name, value in (("u_albedo", tuple(float(v) for v in m.albedo)),
                                ("u_emission", tuple(float(v) for v in m.emission)),
                                ("u_has_texture", tex is not None),
                                ("u_has_emit_texture", d.material in self.r.emit_textures)):
                if name in self.g_prog:
                    self.g_prog[name].value = value
            if tex is not None:
                tex.use(3)
                self.g_prog["u_texture"].value = 3
            if d.material in self.r.emit_textures:
                self.r.emit_textures[d.material].use(4)
                self.g_prog["u_emit_texture"].value = 4
            self.g_vao.render(moderngl.TRIANGLES, vertices=d.count, first=d.first)
        self.afbo.use()
        self.afbo.clear(0.0, 0.0, 0.0, 0.0)
        self.used = self.frames = 0
        self.pfbo.use()
        self.pfbo.clear(0.0, 0.0, 0.0, 0.0)
        for light in self.lights:
            k = LightKind.of(light.kind)
            towards = -np.asarray(light.direction, float) if k == LightKind.DIRECTIONAL else \
                np.asarray(light.direction, float)
            self._add(self.pfbo, k, np.asarray(light.position, float), towards,
                      np.asarray(light.intensity, float), 0.0,
                      (math.cos(light.inner_cone), math.cos(light.outer_cone)))

    def restart(self, camera):
        self.camera = camera
        self._gbuffer()

    def _faces(self, pos):
        near = 1e-4 * self.extent
        proj = perspective(math.pi / 2, 1.0, near, 4.0 * self.extent)
        return [proj @ look_at(pos, f, u) for f, u in FACES]

    def _ortho(self, towards):
        """The orthographic view of the scene from far along `towards`."""
        lo, hi = self.r.bake.scene.bounds()
        c = 0.5 * (lo + hi)
        R = 0.5 * self.extent * 1.01
        up = (0.0, 1.0, 0.0) if abs(towards[1]) < 0.9 else (1.0, 0.0, 0.0)
        view = look_at(c + towards * 2 * R, -towards, up)
        proj = np.zeros((4, 4))
        proj[0, 0] = proj[1, 1] = 1.0 / R
        proj[2, 2] = -2.0 / (4 * R)
        proj[2, 3] = -1.0
        proj[3, 3] = 1.0
        return proj @ view

    def _add(self, target, kind, pos, normal, power, area, cones=(1.0, 0.0)):
        """Renders one light's shadow map, then adds its irradiance to `target`."""
        import moderngl
        ctx, s = self.ctx, self.shadow_size
        self.sfbo.use()
        directional = kind == LightKind.DIRECTIONAL
        self.sfbo.clear(*((-1e30,) * 4 if directional else (1e30,) * 4), depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        self.s_prog["u_directional"].value = directional
        self.s_prog["u_light"].value = tuple(float(x) for x in (normal if directional else pos))
        faces = [self._ortho(np.asarray(normal, float))] * 6 if directional else self._faces(pos)
        for f, m in enumerate(faces[:1] if directional else faces):
            ctx.viewport = (f * s, 0, s, s)
            self.s_prog["u_view_proj"].write(m.T.astype(np.float32).tobytes())
            self.s_vao.render(moderngl.TRIANGLES)
        target.use()
        ctx.viewport = (0, 0, *self.size)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        p = self.p_prog
        self.g_position.use(0)
        self.g_normal.use(1)
        self.shadow.use(2)
        p["u_position"].value, p["u_normal"].value, p["u_shadow"].value = 0, 1, 2
        p["u_kind"].value = int(kind)
        p["u_light"].value = tuple(float(x) for x in pos)
        p["u_light_normal"].value = tuple(float(x) for x in normal)
        p["u_power"].value = tuple(float(x) for x in power)
        p["u_area"].value = float(area)
        p["u_cones"].value = tuple(float(x) for x in cones)
        # directions: two texels of the orthographic map (its texel is extent / size wide), more at grazing
        # incidence, where one texel spans a larger step along the direction
        p["u_bias"].value = 2.0 * self.extent / s if directional else 2e-3 * self.extent
        p["u_face"].write(np.stack([m.T for m in faces]).astype(np.float32).tobytes())
        self.p_vao.render(moderngl.TRIANGLES, vertices=3)
        ctx.disable(moderngl.BLEND)

    def frame(self):
        """Adds the next per_frame VPLs; False when the list is used up."""
        idx = np.arange(self.used, min(self.used + self.per_frame, len(self.vpls)))
        if len(idx) == 0:
            return False
        v = self.vpls
        for k in idx:
            self._add(self.afbo, int(v.kind[k]), v.position[k], v.normal[k], v.power[k], v.area[k])
        self.used += len(idx)
        self.frames += 1
        return True

    def image(self) -> np.ndarray:
        """The running mean as linear radiance (height, width, 3) float32,
        rows top to bottom: emission + albedo / pi x (sum of VPL light) /
        draws."""
        w, h = self.size
        acc = np.frombuffer(self.accum.read(), np.float32).reshape(h, w, 4)[::-1, :, :3]
        alb = np.frombuffer(self.g_albedo.read(), np.float32).reshape(h, w, 4)[::-1, :, :3]
        em = np.frombuffer(self.g_emission.read(), np.float32).reshape(h, w, 4)[::-1, :, :3]
        pun = np.frombuffer(self.punct.read(), np.float32).reshape(h, w, 4)[::-1, :, :3]
        draws = max(1, self.used)
        return np.ascontiguousarray(em + alb / math.pi * (pun + acc / draws), np.float32)

    def show(self, exposure, width, height):
        """Draws the running mean, tone-mapped, into the bound framebuffer."""
        import moderngl
        from .context import build_program
        if not hasattr(self, "show_prog"):
            self.show_prog = build_program(self.ctx, "preview_show.vert", "preview_show.frag")
            self.show_vao = self.ctx.vertex_array(self.show_prog, [])
        ctx, p = self.ctx, self.show_prog
        ctx.viewport = (0, 0, width, height)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
        self.accum.use(0)
        self.g_albedo.use(1)
        self.g_emission.use(2)
        self.punct.use(3)
        p["u_accum"].value, p["u_albedo"].value, p["u_emission"].value, p["u_punctual"].value = 0, 1, 2, 3
        p["u_draws"].value = float(max(1, self.used))
        p["u_exposure"].value = float(exposure)
        self.show_vao.render(moderngl.TRIANGLES, vertices=3)

    def release(self):
        if hasattr(self, "show_prog"):
            self.show_vao.release()
            self.show_prog.release()
        for o in (self.g_vao, self.s_vao, self.p_vao, self.g_prog, self.s_prog, self.p_prog, *self.gtex,
                  self.gdepth, self.gfbo, self.shadow, self.sdepth, self.sfbo, self.accum, self.afbo, self.punct,
                  self.pfbo):
            o.release()
