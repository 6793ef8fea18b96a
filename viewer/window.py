"""The walkthrough window: glfw and input (the only module that imports
glfw). Keys and mouse become `Controls` for the pure-maths camera
(camera.py); drawing is the Renderer's (renderer.py).

    W A S D / Q E   move (forward, left, back, right / down, up); Shift: faster
    mouse drag      look around (hold a button)       wheel   field of view
    1 .. 9          jump to the file's cameras          F12     screenshot (PNG)
    + / -           exposure up / down (1/2 EV)         0       automatic exposure
    M or F1 .. F5   view: lightmap, irradiance, albedo, texel checker, pages
    P               progressive instant-radiosity preview on/off (restarts when the camera moves)
    B               bicubic lightmap filtering on/off   Esc     quit
    O               drop a sphere in front of the camera, lit by the bake's probes (again: remove it)
    G               show the probes as small spheres lit by their SH (invalid ones red) on/off
    N               choose the object the arrow keys move: the sphere, then each of the bake's dynamic
                    meshes (voxbake bake --dynamic NODE), lit by the probes wherever they go
    arrow keys      move that object (left, right, away, nearer); Page Up / Page Down: up, down

Scripted input (`--script FILE.json`, for tests and demos): a list of
events {"frame": n, "key": "W", "action": "press" | "release"},
{"frame": n, "drag": [dx, dy]}, {"frame": n, "scroll": s}; they go through
the same handlers as glfw's callbacks, with a fixed time step per frame.
"""
from __future__ import annotations

import json
import os
import time

import numpy as np

from baker.errors import GLError, VoxgiError
from baker.scene import camera_for

from .camera import Controls, FlyCamera
from .renderer import MODES

MOVE_KEYS = {"W": (0, 1), "S": (0, -1), "D": (1, 1), "A": (1, -1), "E": (2, 1), "Q": (2, -1)}
OBJECT_KEYS = {"RIGHT": (0, 1), "LEFT": (0, -1), "UP": (1, 1), "DOWN": (1, -1), "PAGEUP": (2, 1), "PAGEDOWN": (2, -1)}
SPHERE_SIZE = 0.03    # the dropped sphere's radius, a share of the scene's diagonal
SPHERE_AHEAD = 0.12   # ... and how far ahead of the camera it is dropped
EV_STEP = 0.5


class InputState:
    """Keys held, mouse motion and wheel since the last frame, and the
    discrete key presses to act on."""

    def __init__(self):
        self.held = set()
        self.look = [0.0, 0.0]
        self.scroll = 0.0
        self.pressed = []
        self.dragging = False

    def key(self, name, action):
        if action == "press":
            self.held.add(name)
            self.pressed.append(name)
        elif action == "release":
            self.held.discard(name)

    def drag(self, dx, dy):
        self.look[0] += dx
        self.look[1] += dy

    def wheel(self, s):
        self.scroll += s

    def controls(self) -> Controls:
        move = [0.0, 0.0, 0.0]
        for k, (axis, sign) in MOVE_KEYS.items():
            if k in self.held:
                move[axis] += sign
        c = Controls(tuple(move), "SHIFT" in self.held, tuple(self.look), self.scroll)
        self.look = [0.0, 0.0]
        self.scroll = 0.0
        return c


class Overlay:
    """Text in the top-left corner: drawn by Pillow into a texture when it
    changes, blended over the frame."""

    def __init__(self, ctx):
        from .context import build_program
        self.ctx = ctx
        self.program = build_program(ctx, "overlay.vert", "overlay.frag")
        self.text = None
        self.tex = None
        self.vbo = ctx.buffer(reserve=6 * 4 * 4)
        self.vao = ctx.vertex_array(self.program, [(self.vbo, "2f 2f", "in_pos", "in_uv")])

    def draw(self, text, width, height):
        import moderngl
        from PIL import Image, ImageDraw, ImageFont
        if text != self.text:
            font = ImageFont.load_default()
            w = int(ImageDraw.Draw(Image.new("L", (1, 1))).textlength(text, font=font)) + 12
            img = Image.new("RGBA", (w, 20), (0, 0, 0, 150))
            ImageDraw.Draw(img).text((6, 4), text, fill=(255, 255, 255, 255), font=font)
            if self.tex is not None:
                self.tex.release()
            self.tex = self.ctx.texture(img.size, 4, img.tobytes())
            self.text = text
        w, h = self.tex.size
        quad = np.array([[8, 8, 0, 0], [8 + w, 8, 1, 0], [8 + w, 8 + h, 1, 1],
                         [8, 8, 0, 0], [8 + w, 8 + h, 1, 1], [8, 8 + h, 0, 1]], np.float32)
        self.vbo.write(quad.tobytes())
        self.program["u_screen"].value = (float(width), float(height))
        self.tex.use(0)
        self.ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        self.ctx.enable(moderngl.BLEND)
        self.ctx.blend_func = moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA
        self.vao.render(moderngl.TRIANGLES)
        self.ctx.disable(moderngl.BLEND)


def auto_exposure_ev(ctx, renderer, camera) -> float:
    """EV that maps the view's log-average luminance to 0.18 (as the CPU
    images), from a small linear render."""
    from baker.render.images import auto_exposure
    from .snapshot import render_offscreen
    img = render_offscreen(ctx, renderer, camera, 96, 64, samples=1)
    return float(np.log2(auto_exposure(img)))


def load_script(path):
    try:
        with open(path) as f:
            events = json.load(f)
        assert isinstance(events, list)
        for e in events:
            assert isinstance(e, dict) and isinstance(e.get("frame"), int)
    except (OSError, ValueError, AssertionError) as e:
        raise VoxgiError(f"not a valid input script (a JSON list of events with a 'frame'): {e}", path) from None
    return events


class Walkthrough:
    def __init__(self, bake, width=1280, height=720, camera=None, exposure_ev=None, mode="lightmap",
                 script=None, frames=None, screenshot=None, fixed_dt=None, title="voxview", show_probes=False):
        self.bake = bake
        self.size = (width, height)
        self.start_camera = camera
        self.exposure_ev = exposure_ev
        self.mode = mode
        self.bicubic = False
        self.script = script or []
        self.frames = frames
        self.screenshot_path = screenshot
        self.fixed_dt = fixed_dt if fixed_dt is not None else (1 / 30 if script else None)
        self.title = title
        self.input = InputState()
        self.shots = []
        self.preview_on = mode == "preview"
        if mode == "preview":
            self.mode = "lightmap"
        self.preview = None
        self.sphere = None   # objects.Sphere the user dropped (O), lit by the probes
        self.offsets = [np.zeros(3) for _ in bake.scene.dynamic]   # how far each dynamic mesh was moved
        self.selected = 0 if bake.scene.dynamic else None   # what the arrow keys move: a dynamic mesh, or None: the sphere
        self.show_probes = show_probes   # the probes drawn (G)
        self.note = ""
        lo, hi = bake.scene.bounds()   # once: the bounds of a large scene take milliseconds, a frame's budget
        self.extent = float(np.linalg.norm(hi - lo)) or 1.0

    # -- glfw ---------------------------------------------------------------
    def _open(self):
        import glfw
        if not os.environ.get("DISPLAY") and not os.environ.get("WAYLAND_DISPLAY"):
            raise GLError("no display to open a window on (DISPLAY is not set); for images without a window use "
                          "`voxview snapshot`, or run under Xvfb (`xvfb-run -a voxview ...`)")
        if not glfw.init():
            raise GLError("glfw could not initialise the display (is DISPLAY an X server that runs?)")
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 3)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
        win = glfw.create_window(self.size[0], self.size[1], self.title, None, None)
        if not win:
            glfw.terminate()
            raise GLError("glfw could not open an OpenGL 3.3 window on this display")
        glfw.make_context_current(win)
        glfw.swap_interval(0)
        return glfw, win

    def _callbacks(self, glfw, win):
        names = {getattr(glfw, f"KEY_{k}"): k for k in "WASDQEMBPOGN0123456789"}
        names.update({glfw.KEY_LEFT: "LEFT", glfw.KEY_RIGHT: "RIGHT", glfw.KEY_UP: "UP", glfw.KEY_DOWN: "DOWN",
                      glfw.KEY_PAGE_UP: "PAGEUP", glfw.KEY_PAGE_DOWN: "PAGEDOWN"})
        names.update({glfw.KEY_LEFT_SHIFT: "SHIFT", glfw.KEY_RIGHT_SHIFT: "SHIFT", glfw.KEY_F12: "F12",
                      glfw.KEY_ESCAPE: "ESCAPE", glfw.KEY_EQUAL: "+", glfw.KEY_KP_ADD: "+", glfw.KEY_MINUS: "-",
                      glfw.KEY_KP_SUBTRACT: "-", glfw.KEY_F1: "F1", glfw.KEY_F2: "F2", glfw.KEY_F3: "F3",
                      glfw.KEY_F4: "F4", glfw.KEY_F5: "F5"})
        actions = {glfw.PRESS: "press", glfw.RELEASE: "release"}
        last = [None]

        def on_key(w, key, scancode, action, mods):
            if key in names and action in actions:
                self.input.key(names[key], actions[action])

        def on_button(w, button, action, mods):
            self.input.dragging = action == glfw.PRESS
            last[0] = glfw.get_cursor_pos(w) if self.input.dragging else None

        def on_cursor(w, x, y):
            if self.input.dragging and last[0] is not None:
                self.input.drag(x - last[0][0], y - last[0][1])
                last[0] = (x, y)

        def on_scroll(w, dx, dy):
            self.input.wheel(dy)
        glfw.set_key_callback(win, on_key)
        glfw.set_mouse_button_callback(win, on_button)
        glfw.set_cursor_pos_callback(win, on_cursor)
        glfw.set_scroll_callback(win, on_scroll)

    def _scripted(self, frame):
        for e in self.script:
            if e["frame"] != frame:
                continue
            if "key" in e:
                self.input.key(str(e["key"]).upper(), e.get("action", "press"))
            if "drag" in e:
                self.input.drag(*map(float, e["drag"]))
            if "scroll" in e:
                self.input.wheel(float(e["scroll"]))

    # -- actions --------------------------------------------------------------
    def _act(self, key, ctx, renderer, camera):
        cams = self.bake.scene.cameras
        if key.isdigit() and key != "0":
            i = int(key) - 1
            if i < len(cams):
                return FlyCamera.from_camera(cams[i], camera.speed), True
        elif key == "0":
            self.exposure_ev = auto_exposure_ev(ctx, renderer, camera)
        elif key == "+":
            self.exposure_ev += EV_STEP
        elif key == "-":
            self.exposure_ev -= EV_STEP
        elif key == "M":
            self.mode = MODES[(MODES.index(self.mode) + 1) % len(MODES)]
        elif key in ("F1", "F2", "F3", "F4", "F5"):
            self.mode = MODES[int(key[1]) - 1]
        elif key == "B":
            self.bicubic = not self.bicubic
        elif key == "P":
            self.preview_on = not self.preview_on
        elif key == "O":
            self._toggle_sphere(camera)
        elif key == "N":
            self._select_next()
        elif key == "G":
            if self.bake.probes is None:
                self.note = "no probes in this bake (baked with --no-probes)"
            else:
                self.show_probes = not self.show_probes
        elif key == "F12":
            self._screenshot(ctx)
        elif key == "ESCAPE":
            return camera, False
        return camera, True

    def _toggle_sphere(self, camera):
        from .objects import Sphere
        if self.sphere is not None:
            self.sphere = None
            self.selected = 0 if self.bake.scene.dynamic else None
        elif self.bake.probes is None:
            self.note = "no probes in this bake (baked with --no-probes)"
        else:
            e = self.extent
            centre = np.asarray(camera.position) + SPHERE_AHEAD * e * camera.forward
            self.sphere = Sphere(tuple(float(v) for v in centre), SPHERE_SIZE * e)
            self.selected = None

    def _select_next(self):
        """N: the next movable object (the sphere if dropped, then each
        dynamic mesh), named in the status line."""
        choices = ([None] if self.sphere is not None else []) + list(range(len(self.bake.scene.dynamic)))
        if not choices:
            self.note = "nothing to move: O drops a sphere (dynamic meshes: voxbake bake --dynamic NODE)"
            return
        at = choices.index(self.selected) if self.selected in choices else -1
        self.selected = choices[(at + 1) % len(choices)]
        self.note = "moving " + ("the sphere" if self.selected is None else
                                 repr(self.bake.scene.dynamic[self.selected].name))

    def objects(self) -> tuple:
        """What the lightmap view draws lit by the probes: the sphere, and
        each dynamic mesh where it was moved."""
        from .objects import Placed
        placed = tuple(Placed(i, tuple(float(v) for v in off)) for i, off in enumerate(self.offsets))
        return ((self.sphere,) if self.sphere is not None else ()) + placed

    def _move_sphere(self, camera, dt):
        """The selected object (the sphere or a dynamic mesh) moved by the
        arrow keys held: along the camera's right, its forward on the ground
        plane, and up."""
        from dataclasses import replace as _replace
        if self.selected is None and self.sphere is None:
            return
        flat = np.array([camera.forward[0], 0.0, camera.forward[2]])
        flat /= np.linalg.norm(flat) or 1.0
        axes = (camera.right, flat, np.array([0.0, 1.0, 0.0]))
        step = np.zeros(3)
        for k, (axis, sign) in OBJECT_KEYS.items():
            if k in self.input.held:
                step += sign * axes[axis]
        if step.any():
            if self.selected is not None:
                self.offsets[self.selected] = self.offsets[self.selected] + 0.1 * self.extent * dt * step
                return
            c = np.asarray(self.sphere.center) + 0.1 * self.extent * dt * step
            self.sphere = _replace(self.sphere, center=tuple(float(v) for v in c))

    def _preview_frame(self, ctx, renderer, camera, w, h):
        """One frame of the progressive preview: restarts when the camera or
        the window changed, adds the next VPLs, shows the running mean."""
        from .preview import Preview
        if self.preview is None or self.preview.size != (w, h):
            if self.preview is not None:
                self.preview.release()
            self.preview = Preview(ctx, renderer, camera, w, h)
        elif self.preview.camera != camera:
            self.preview.restart(camera)
        self.preview.frame()
        ctx.screen.use()
        ctx.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
        self.preview.show(2.0 ** self.exposure_ev, w, h)

    def _screenshot(self, ctx, path=None):
        from PIL import Image

        from baker.fileio import atomic_write
        w, h = self.size
        raw = np.frombuffer(ctx.screen.read(components=3), np.uint8).reshape(h, w, 3)[::-1]
        path = path or time.strftime("voxview-%Y%m%d-%H%M%S.png")
        atomic_write(path, lambda tmp: Image.fromarray(np.ascontiguousarray(raw), "RGB").save(tmp, format="PNG"))
        self.shots.append(path)
        print(f"saved {path}")

    def run(self) -> dict:
        """Opens the window and runs until Esc, the window's close button or
        `frames` frames; returns {'frames', 'seconds', 'camera', 'shots'}."""
        import moderngl
        glfw, win = self._open()
        try:
            self._callbacks(glfw, win)
            ctx = moderngl.create_context()
            from .renderer import Renderer
            renderer = Renderer(ctx, self.bake, interactive=True)
            cam0 = self.start_camera if self.start_camera is not None else camera_for(self.bake.scene, None)
            lo, hi = self.bake.scene.bounds()
            camera = FlyCamera.from_camera(cam0, speed=0.15 * float(np.linalg.norm(hi - lo)))
            if self.exposure_ev is None:
                self.exposure_ev = auto_exposure_ev(ctx, renderer, camera)
            overlay = Overlay(ctx)
            frame, t_last, t0 = 0, time.perf_counter(), time.perf_counter()
            fps, fps_t, fps_n = 0.0, t0, 0
            running = True
            while running and not glfw.window_should_close(win):
                glfw.poll_events()
                self._scripted(frame)
                now = time.perf_counter()
                dt = self.fixed_dt if self.fixed_dt is not None else min(now - t_last, 0.1)
                t_last = now
                for key in self.input.pressed:
                    camera, running = self._act(key, ctx, renderer, camera)
                    if not running:
                        break
                self.input.pressed.clear()
                camera = camera.step(dt, self.input.controls())
                self._move_sphere(camera, dt)
                w, h = glfw.get_framebuffer_size(win)
                self.size = (w, h)
                if self.preview_on:
                    self._preview_frame(ctx, renderer, camera, w, h)
                else:
                    ctx.screen.use()
                    ctx.clear(0.0, 0.0, 0.0, 1.0, depth=1.0)
                    objects = self.objects() if self.mode == "lightmap" else ()
                    renderer.render(camera, w, h, self.mode, 2.0 ** self.exposure_ev, True, self.bicubic, objects,
                                    self.show_probes and self.mode == "lightmap")
                fps_n += 1
                if now - fps_t >= 0.5:
                    fps, fps_t, fps_n = fps_n / (now - fps_t), now, 0
                rate = f"{fps:5.1f} fps" if fps else "   -- fps"
                view = (f"preview {self.preview.used} VPLs" if self.preview_on and self.preview is not None
                        else f"{self.mode}{' bicubic' if self.bicubic else ''}")
                overlay.draw(f"{rate}   {view}   EV {self.exposure_ev:+.1f}   F1-F5 views, P preview, "
                             f"+/- exposure, 1-9 cameras, O sphere, N next object, G probes{'   ' + self.note if self.note else ''}", w, h)
                frame += 1
                if self.frames is not None and frame >= self.frames:
                    if self.screenshot_path:
                        self._screenshot(ctx, self.screenshot_path)
                    running = False
                glfw.swap_buffers(win)
            return {"frames": frame, "seconds": time.perf_counter() - t0, "camera": camera, "shots": self.shots}
        finally:
            glfw.destroy_window(win)
            glfw.terminate()
