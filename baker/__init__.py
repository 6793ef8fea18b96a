"""voxgi baker: scene -> voxels -> solution -> images (and, as they land,
VPLs -> light tree -> lightmaps -> bake file).

The library face (the command line `voxbake` is a thin layer over it):

    scene = load_scene("scenes/cornell_box.glb")   # or a built-in name: "cornell_box"
    voxels = voxelize(scene, resolution=64)
    solution = solve(scene, solver_config("default"))
    image = render(scene, method="voxels", solution=solution)
    write_image("out.png", image)
"""
__version__ = "0.1.0"

# first of all, so that a Ctrl-C or SIGTERM during the imports below is answered once the command runs (cli.run)
from .startup import hold_interrupts  # noqa: E402

hold_interrupts()

import os as _os  # noqa: E402

# numba's OpenMP threads spin while they wait for work by default; beside another busy process a spinning
# thread holds the core that the late thread needs (the propagation meets a barrier per batch of
# families), so threads that sleep lose less beside other work and nothing on a quiet machine
# (bench/threads.py). The user's own setting wins.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
# numpy asks the kernel for transparent huge pages under every array of 4 MiB or more; where the guest's memory
# is backed lazily by its host (a Firecracker VM, as our CI and benchmark machines are) first touching a huge
# page costs several times its small pages, and a bake makes gigabytes of short-lived per-texel arrays
# (bench/results/texel_shading.md). Set before numpy is imported; the user's own setting wins.
_os.environ.setdefault("NUMPY_MADVISE_HUGEPAGE", "0")

from .kernel_cache import sync as _sync_kernel_cache  # noqa: E402

_sync_kernel_cache()  # cached kernels compiled from other sources are dropped (kernel_cache.py)

from .config import SolverConfig  # noqa: E402
from .presets import PRESETS, Preset, bake_config, lightcuts_config, solver_config  # noqa: E402
from .errors import BakeFileError, BudgetError, ConfigError, GLError, SceneError, VoxgiError, VoxgiWarning  # noqa: E402
from .render import read_exr, render, write_image  # noqa: E402
from .scene import Scene, builtin_scenes, load_scene  # noqa: E402
from .solve import Solution, solve  # noqa: E402
from .solve.audit import audit  # noqa: E402
from .voxels import Voxels, voxelize  # noqa: E402

__all__ = ["BakeFileError", "BudgetError", "ConfigError", "GLError", "PRESETS", "Preset", "Scene", "SceneError", "Solution",
           "SolverConfig", "Voxels", "VoxgiError", "VoxgiWarning", "__version__", "audit", "bake_config", "builtin_scenes", "lightcuts_config",
           "load_scene", "read_exr", "render", "solve", "solver_config", "voxelize", "write_image"]
