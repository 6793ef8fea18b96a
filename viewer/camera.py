"""The walkthrough camera: pure maths, no GL, driven by an explicit time
step (docs/design.md section 9).

A fly camera: position, yaw (about +Y, 0 looks along -Z as glTF's cameras
do), pitch (clamped short of straight up or down), vertical field of
view. `step` moves it by the keys held and the mouse motion over `dt`
seconds and returns a new camera: the same inputs give the same camera,
whatever the frame rate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

MAX_PITCH = math.radians(89.0)
MIN_FOV, MAX_FOV = math.radians(10.0), math.radians(120.0)


@dataclass(frozen=True)
class Controls:
    """What the user holds this frame: move (forward, right, up) each in
    -1..1; fast (Shift); look (dx, dy) mouse motion in pixels; scroll
    (wheel steps, + zooms in)."""
    move: tuple = (0.0, 0.0, 0.0)
    fast: bool = False
    look: tuple = (0.0, 0.0)
    scroll: float = 0.0


@dataclass(frozen=True)
class FlyCamera:
    position: tuple
    yaw: float
    pitch: float
    yfov: float
    speed: float = 1.0          # scene units per second (Shift: FAST times that)
    sensitivity: float = 0.003  # radians per pixel of mouse motion
    FAST = 4.0
    ZOOM = 1.1                  # field of view factor per wheel step

    @classmethod
    def from_camera(cls, camera, speed=1.0) -> "FlyCamera":
        """From a scene Camera (position, forward, yfov); its roll is dropped."""
        f = np.asarray(camera.forward, float)
        f = f / np.linalg.norm(f)
        pitch = math.asin(max(-1.0, min(1.0, f[1])))
        yaw = math.atan2(f[0], -f[2])
        return cls(tuple(float(v) for v in camera.position), yaw, max(-MAX_PITCH, min(MAX_PITCH, pitch)),
                   float(camera.yfov), float(speed))

    @property
    def forward(self) -> np.ndarray:
        cp = math.cos(self.pitch)
        return np.array([cp * math.sin(self.yaw), math.sin(self.pitch), -cp * math.cos(self.yaw)])

    @property
    def right(self) -> np.ndarray:
        return np.array([math.cos(self.yaw), 0.0, math.sin(self.yaw)])

    @property
    def up(self) -> np.ndarray:
        return np.cross(self.right, self.forward)

    def step(self, dt: float, c: Controls) -> "FlyCamera":
        """The camera dt seconds later under controls c."""
        yaw = self.yaw + c.look[0] * self.sensitivity
        pitch = max(-MAX_PITCH, min(MAX_PITCH, self.pitch - c.look[1] * self.sensitivity))
        turned = replace(self, yaw=yaw, pitch=pitch)
        v = self.speed * (self.FAST if c.fast else 1.0) * dt
        d = (turned.forward * c.move[0] + turned.right * c.move[1] + np.array([0.0, 1.0, 0.0]) * c.move[2])
        pos = np.asarray(self.position) + v * d
        fov = max(MIN_FOV, min(MAX_FOV, self.yfov / self.ZOOM ** c.scroll))
        return replace(turned, position=tuple(float(x) for x in pos), yfov=fov)


def look_at(position, forward, up) -> np.ndarray:
    """4x4 view matrix (world -> camera, camera looking along -Z), float64."""
    f = np.asarray(forward, float)
    f = f / np.linalg.norm(f)
    r = np.cross(f, np.asarray(up, float))
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3] = r, u, -f
    m[:3, 3] = -m[:3, :3] @ np.asarray(position, float)
    return m


def perspective(yfov, aspect, near, far) -> np.ndarray:
    """4x4 OpenGL projection (clip z in -w..w)."""
    t = 1.0 / math.tan(yfov / 2)
    m = np.zeros((4, 4))
    m[0, 0] = t / aspect
    m[1, 1] = t
    m[2, 2] = (far + near) / (near - far)
    m[2, 3] = 2 * far * near / (near - far)
    m[3, 2] = -1.0
    return m


def view_of(camera) -> np.ndarray:
    """View matrix of a scene Camera or a FlyCamera."""
    return look_at(camera.position, camera.forward, camera.up)
