import numpy as np
import pytest

from baker.solve.directions import direction_set
from baker.solve.propagate import LineSweeper
from baker.voxels import voxelize
from baker.scene.gltf_write import GltfBuilder
from scenes.generate import box, closed_box, cornell_box, furnace_box, furnace_obstacles, quad, thin_wall, two_rooms
from tests.threads import same_for_any_thread_count
from tests.naive import line_inputs, propagate_lines


def gather_both(v, radiosity, dirs, offsets, sweeper=None):
    sw = sweeper or LineSweeper(v)
    fast = sw.gather(radiosity, dirs, offsets)
    # the kernel works in cells: the reference reads the same voxels in grid coordinates, taken from the Voxels
    # themselves, not from the sweeper it checks
    ref = line_inputs(v)
    slow = propagate_lines(v.cell, np.zeros(3), ref["centroid"], ref["normal"], radiosity, dirs.vectors, dirs.axis,
                           dirs.unit, dirs.solid_angle / np.pi, offsets, 1.0, cut=ref["cut"], sheet=ref["sheet"],
                           flat=ref["flat"], edge=ref["edge"], foot=ref["foot"])
    return fast, slow


def assert_matches_reference(v, seed, offset_seed):
    """Kernel and plain-Python reference agree on random radiosity (r = 2);
    returns the kernel's gathered sums."""
    radiosity = np.random.default_rng(seed).random((len(v), 3))
    dirs = direction_set(2)
    sw = LineSweeper(v)
    (g, s), (g_ref, s_ref) = gather_both(v, radiosity, dirs, sw.offsets(dirs, offset_seed, 3), sw)
    np.testing.assert_allclose(g, g_ref, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(s, s_ref, rtol=1e-12, atol=1e-14)
    return g


@pytest.mark.parametrize("name,builder,res", [
    ("obstacles", furnace_obstacles, 8),
    ("rooms_midcell", lambda: two_rooms(wall_x=1.0 + 0.5 * 2 / 10), 10),
    ("cornell", cornell_box, 8),
    ("thin_wall", thin_wall, 10),  # a double-sided sheet: its faces back to back
    ("closed_box_double_sided", lambda: closed_box(double_sided=True), 10),
])
def test_kernel_matches_slow_reference(make_scene, name, builder, res):
    g = assert_matches_reference(voxelize(make_scene(builder(), f"prop_{name}"), res), 1, 5)
    assert (g > 0).any()


def terraces(res, tilt=0.02):
    """A closed box with a floor of strips on one slightly tilted plane
    normal, stepping up and down along x by fractions of a cell (some within
    tau, some beyond): lines along x lie in the strips, all their voxels
    wait on the line at once, and a step beyond tau must block them."""
    h = 1.0 / res
    n = np.array([tilt, 1.0, 0.0])
    b = GltfBuilder()
    m = b.material("grey", (0.6,) * 3)
    b.mesh("shell", *box((0, 0, 0), (1, 1, 1), inward=True), m)
    steps = [0.0, 0.05, -0.3, 0.6, 0.02, -0.08, 0.45]  # cells, step after step
    xs = np.linspace(0.0, 1.0, len(steps) + 1)
    y = 0.5 * h + 3 * h
    for i, step in enumerate(steps):
        y += step * h
        x0, x1 = xs[i], xs[i + 1]
        # the strip lies on the plane n . p = n . (x0, y, 0): the same normal everywhere
        y0, y1 = y - tilt * (x0 - xs[0]), y - tilt * (x1 - xs[0])
        b.mesh(f"strip{i}", *quad((x0, y0, 0.2), (x1, y1, 0.2), (x1, y1, 0.8), (x0, y0, 0.8), facing=n), m)
    return b


@pytest.mark.parametrize("res", [16, 24])
def test_lines_lying_in_a_surface_match_reference(make_scene, res):
    """The waiting list's bound (one surface's run along a line tested in
    O(1)) gives what testing every waiting voxel gives."""
    assert_matches_reference(voxelize(make_scene(terraces(res), f"prop_terraces_{res}"), res), 4, 1)


def test_hashed_line_table_equals_dense(make_scene):
    scene = make_scene(cornell_box(), "prop_cornell_hash")
    v = voxelize(scene, 16)
    dirs = direction_set(3)
    radiosity = np.random.default_rng(2).random((len(v), 3))
    dense = LineSweeper(v)
    hashed = LineSweeper(v)
    hashed.table_size = 1024  # far below the dense range: every family hashes its line ids
    assert hashed.line_table(dirs)[1] and not dense.line_table(dirs)[1]
    off = dense.offsets(dirs, 0, 2)
    a = dense.gather(radiosity, dirs, off)
    b = hashed.gather(radiosity, dirs, off)
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])


def test_closed_box_gathers_uniform_radiosity_exactly(make_scene):
    v = voxelize(make_scene(furnace_box(), "prop_fb"), 12)
    sw = LineSweeper(v)
    for r in (1, 3, 6):
        d = direction_set(r)
        h = sw.irradiance(np.ones((len(v), 3)), d, sw.offsets(d, 1, r))
        np.testing.assert_allclose(h, 1.0, rtol=1e-12)


@pytest.mark.parametrize("res", [37, 45, 59])
def test_closed_room_on_no_grid_gathers_uniform_radiosity_exactly(make_scene, res):
    """A closed 2 m room at cell sizes that do not divide it: its low walls
    lie on the grid's first cell boundary, its high walls inside cells.
    Every line from every voxel meets a surface. Before grid coordinates
    were snapped to cell boundaries (voxels.clip.to_grid) the low walls fell
    in the cells outside the room, and lines from them ran outside the
    high walls' cells: 0.5-1.2% of the walls' lines found nothing, and
    scan_room came out 2% dark (measured)."""
    b = GltfBuilder()
    b.mesh("room", *box((-1, 0, -1), (1, 2, 1), inward=True), b.material("wall", (0.7,) * 3))
    v = voxelize(make_scene(b, "prop_room"), res)
    sw = LineSweeper(v)
    d = direction_set(4)
    h = sw.irradiance(np.ones((len(v), 3)), d, sw.offsets(d, 1, 1))
    np.testing.assert_allclose(h, 1.0, rtol=1e-9)


def test_same_result_for_any_thread_count(make_scene):
    v = voxelize(make_scene(cornell_box(), "prop_cornell_thr"), 16)
    d = direction_set(4)
    sw = LineSweeper(v)
    radiosity = np.random.default_rng(3).random((len(v), 3))
    g, s = same_for_any_thread_count(lambda: sw.gather(radiosity, d, sw.offsets(d, 0, 2)))
    assert (g > 0).any() and (s > 0).all()


def test_offsets_are_seeded_and_in_range():
    d = direction_set(5)
    sw_off = LineSweeper.offsets(None, d, 7, 2)
    a = d.vectors[np.arange(d.n_families), d.axis]
    assert (sw_off >= 0).all() and (sw_off < a[:, None]).all()
    np.testing.assert_array_equal(sw_off, LineSweeper.offsets(None, d, 7, 2))
    assert not np.array_equal(sw_off, LineSweeper.offsets(None, d, 7, 3))
