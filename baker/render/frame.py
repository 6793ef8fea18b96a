"""One frame of a scene by any method: the registry of render methods and
the pipeline each runs (load -> BVH -> solution -> lights -> image), as
`voxbake render` and the library's `render` use it."""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..config import LightcutsConfig, SolverConfig
from ..errors import VoxgiError

MAX_PIXELS = 64_000_000
SPP_CAP = 1 << 20  # pathtrace: the most samples per pixel a --noise or --time-limit run takes unless told


@dataclass(frozen=True)
class Method:
    """name; about: its --help paragraph; solves: it needs the voxel
    solution; bake: it draws a bake file, not a scene."""
    name: str
    about: str
    solves: bool = False
    bake: bool = False


METHODS = {m.name: m for m in (
    Method("pathtrace", "reference path tracer (NEE + MIS, Russian roulette, scrambled Sobol samples): unbiased, "
                        "the yardstick for the other methods; --noise and --time-limit stop it when it is good "
                        "enough"),
    Method("voxels", "the voxel GI solution shown directly: each visible point takes its voxel's outgoing "
                     "radiance (the 'direct voxel view')", solves=True),
    Method("lightcuts", "the quality frame: the voxel solution as virtual point lights, shaded by lightcuts (edge "
                        "pixels anti-aliased 4x4)", solves=True),
    Method("instant-radiosity", "the progressive preview on the CPU: the VPLs in a fixed order drawn by power, "
                                "--vpls-per-frame a frame, running average", solves=True),
    Method("lightmap", "a bake file (`voxbake bake`) as a viewer shows it: albedo x lightmap irradiance / pi + "
                       "emission (give the .glb as SCENE)", bake=True),
)}


@dataclass(frozen=True)
class RenderSettings:
    """What to render: the method, the image size, path tracing's samples
    per pixel (or a stop at `noise` relative RMSE or after `time_limit`
    seconds), the seed, the solver and lightcuts settings of the methods
    that need them (None: the default preset's), and instant radiosity's
    VPLs per frame, frames and stopping change; path_bounces caps the
    path tracer's reflections (1: direct light only), to split an image's
    error by bounce."""
    method: str = "pathtrace"
    width: int = 512
    height: int = 512
    spp: int = 64
    seed: int = 0
    time_limit: float | None = None
    noise: float | None = None
    solver: SolverConfig | None = None
    lightcuts: LightcutsConfig | None = None
    vpls_per_frame: int = 16
    frames: int = 256
    ir_tolerance: float = 0.0
    path_bounces: int | None = None   # pathtrace: reflections counted at most (None: all)

    def __post_init__(self):
        if self.method not in METHODS:
            raise VoxgiError(f"unknown method {self.method!r}; choose from {', '.join(METHODS)}")
        if self.width < 1 or self.height < 1 or self.width * self.height > MAX_PIXELS:
            raise VoxgiError(f"image size {self.width}x{self.height} out of range")
        if self.spp < 1:
            raise VoxgiError(f"--spp must be at least 1 (got {self.spp})")
        if self.time_limit is not None and not self.time_limit > 0:
            raise VoxgiError(f"--time-limit must be a positive number of seconds (got {self.time_limit})")
        if self.noise is not None and not self.noise > 0:
            raise VoxgiError(f"--noise must be a positive fraction, e.g. 0.02 for 2% (got {self.noise})")
        if self.path_bounces is not None and self.method != "pathtrace":
            raise VoxgiError("--path-bounces applies to --method pathtrace")
        if self.path_bounces is not None and not 0 <= self.path_bounces <= 999:
            raise VoxgiError(f"--path-bounces must lie in 0..999 (got {self.path_bounces})")
        if self.adaptive and self.method != "pathtrace":
            raise VoxgiError("--time-limit and --noise apply to --method pathtrace")
        if self.vpls_per_frame < 1 or self.frames < 1:
            raise VoxgiError("--vpls-per-frame and --frames must be at least 1")

    @property
    def adaptive(self) -> bool:
        return self.time_limit is not None or self.noise is not None


@dataclass(frozen=True)
class Frame:
    """A linear radiance image (height, width, 3) float32, the counts the
    stats file records, one line for the user (empty: none) and the voxel
    solution it used (None: none)."""
    image: np.ndarray
    counts: dict = field(default_factory=dict)
    summary: str = ""
    solution: object | None = None


def render_frame(scene, camera, settings: RenderSettings, stats=None, progress=False, bvh=None, surfaces=None,
                 solution=None) -> Frame:
    """The frame `settings` asks for of `scene` (a Scene or a Prepared; a
    Bake for the 'lightmap' method) seen by `camera` (a Camera). stats: a
    Stats the stages are timed into; progress: show progress bars; bvh,
    surfaces, solution: reuse these instead of building them."""
    from ..scene import prepare
    from ..stats import Stats
    from .camera import camera_array
    stats = stats or Stats("render " + settings.method)
    bake = scene if METHODS[settings.method].bake else None
    with stats.stage("bvh"):
        prepared = prepare(bake.scene if bake is not None else scene, bvh, surfaces)
    world = prepared.scene
    if METHODS[settings.method].solves and solution is None:
        from ..presets import solver_config
        from ..solve import solve
        solution = solve(prepared, settings.solver or solver_config(), stats=stats, progress=progress)
    job = _Job(bake if bake is not None else world, prepared, camera,
               camera_array(camera, settings.width, settings.height), settings, stats, progress, solution)
    frame = _RENDERERS[settings.method](job)
    if not np.isfinite(frame.image).all() or frame.image.min() < 0:
        raise VoxgiError("internal error: non-finite or negative pixels (please report)", world.path)
    return frame


@dataclass(frozen=True)
class _Job:
    """What a renderer reads: the source (the Scene, or the Bake for
    'lightmap'), the Prepared scene, the camera and its packed array."""
    source: object
    prepared: object
    camera: object
    cam: np.ndarray
    settings: RenderSettings
    stats: object
    progress: bool
    solution: object

    @property
    def bvh(self):
        return self.prepared.bvh

    @property
    def surfaces(self):
        return self.prepared.surfaces


def _lights(job, tree=True):
    from ..lights import build_lights
    from ..presets import lightcuts_config
    lc = job.settings.lightcuts or lightcuts_config()
    with job.stats.stage("lights"):
        lights = build_lights(job.prepared, job.solution, lc, tree=tree)
    job.stats.count(**lights.vpls.counts())
    return lc, lights


def _pathtrace(job) -> Frame:
    from ..progress import bar
    from .pathtrace import MAX_BOUNCES, pathtrace
    s = job.settings
    total = None if s.adaptive else s.width * s.height * s.spp
    what = f"{s.spp} spp" if not s.adaptive else "until " + " or ".join(
        ([f"{s.noise:.2%} noise"] if s.noise else []) + ([f"{s.time_limit:g} s"] if s.time_limit else []))
    with job.stats.stage("pathtrace"), bar(total, f"path tracing {what}", "sample", job.progress) as b:
        pt = pathtrace(job.bvh, job.surfaces, job.cam, s.width, s.height, s.spp, s.seed, s.time_limit, s.noise,
                       b.update, MAX_BOUNCES if s.path_bounces is None else s.path_bounces)
    counts = dict(spp=pt.spp, camera_paths=s.width * s.height * pt.spp, noise_estimate=pt.noise,
                  stopped_by=pt.stopped, samples_per_second=s.width * s.height * pt.spp / pt.seconds)
    by = {"spp": "--spp", "noise": "--noise", "time": "--time-limit"}[pt.stopped]
    return Frame(pt.image, counts, f"{pt.spp} spp, estimated noise {pt.noise:.2%} (relative RMSE), stopped by {by}")


def _voxels(job) -> Frame:
    from ..progress import bar
    from .voxelview import render_voxels
    s = job.settings
    with job.stats.stage("voxel_view"), bar(s.height, "voxel view", "row", job.progress) as b:
        image = render_voxels(job.bvh, job.surfaces, job.solution, job.cam, s.width, s.height, b.update)
    return Frame(image, {}, job.solution.summary(), job.solution)


def _lightcuts(job) -> Frame:
    from ..progress import bar
    from .lightcuts_frame import render_lightcuts
    s = job.settings
    lc, lights = _lights(job, tree=not job_gathers(job))
    v = lights.vpls.counts()
    bounce = None
    if job_gathers(job):
        with job.stats.stage("lights"):
            lights, bounce = gathered_lights(lights, job.solution, lc)
    with job.stats.stage("lightcuts_frame"), bar(s.width * s.height, "lightcuts", "point", job.progress) as b:
        image, fs = render_lightcuts(job.bvh, job.surfaces, lights, job.cam, s.width, s.height, lc.epsilon, lc.cap,
                                     b.update, grow=b.grow, bounce=bounce)
    how = (f"{v['vpls_indirect']} indirect" if bounce is None else
           f"the voxels' light gathered by {lc.gather} rays" + (f" at records {lc.gather_spacing:g} cells apart"
                                                                 if lc.gather_spacing else " per point"))
    line = (f"{job.solution.summary()}\nVPLs {v['vpls_direct'] + v['vpls_sky']} ({v['vpls_direct']} direct, "
            f"{v['vpls_sky']} sky), {how}  cut mean {fs.cut_mean:.0f} max {fs.cut_max}  shadow rays/pixel "
            f"{fs.shadow_rays_per_pixel:.0f}")
    return Frame(image, dict(asdict(fs), epsilon=lc.epsilon, cut_cap=lc.cap, gather=lc.gather if bounce else 0),
                 line, job.solution)


def gathered_lights(lights, solution, lc):
    """(the cuts' Lights, Bounced) of a frame that gathers its bounced
    light (LightcutsConfig.gather > 0): the voxels' light by a final
    gather into `solution`, the cuts over the emitters' VPLs alone, the
    sky's directions by cuts of their own. `lights`: build_lights' (its
    tree is not needed: tree=False)."""
    from ..lights import split_lights
    from .lightcuts_frame import Bounced
    sharp, smooth = split_lights(lights, lc.seed, tree=False)
    sky = smooth is not None and smooth.sky is not None and len(smooth.sky) > 0
    return sharp, Bounced(solution, lc.gather, lc.gather_spacing, smooth if sky else None)


def job_gathers(job) -> bool:
    """Whether a lightcuts frame gathers its bounced light (LightcutsConfig.gather)."""
    from ..presets import lightcuts_config
    return (job.settings.lightcuts or lightcuts_config()).gather > 0


def _instant_radiosity(job) -> Frame:
    from ..lights import ordered_vpls
    from ..progress import bar
    from .instant_radiosity import render_instant_radiosity
    s = job.settings
    lc, lights = _lights(job)
    with job.stats.stage("lights"):
        lo, hi = job.prepared.scene.bounds()
        order = ordered_vpls(lights.vpls, s.vpls_per_frame * s.frames, 0.5 * float(np.linalg.norm(hi - lo)), lc.seed)
    with job.stats.stage("instant_radiosity"), bar(s.frames, "instant radiosity", "frame", job.progress) as b:
        image, ir = render_instant_radiosity(job.bvh, job.surfaces, order, job.cam, s.width, s.height,
                                             s.vpls_per_frame, s.frames, s.ir_tolerance, b.update)
    return Frame(image, dict(ir_frames=ir.frames, ir_vpls_used=ir.vpls_used, ir_last_change=ir.change),
                 f"{ir.frames} frames of {s.vpls_per_frame} VPLs (last change {ir.change:.2e})", job.solution)


def _lightmap(job) -> Frame:
    from ..progress import bar
    from .lightmap_view import render_bake
    s = job.settings
    with job.stats.stage("lightmap_view"), bar(s.height, "lightmap view", "row", job.progress) as b:
        image = render_bake(job.source, job.camera, s.width, s.height, b.update, job.bvh)
    return Frame(image)


_RENDERERS = {"pathtrace": _pathtrace, "voxels": _voxels, "lightcuts": _lightcuts,
              "instant-radiosity": _instant_radiosity, "lightmap": _lightmap}
