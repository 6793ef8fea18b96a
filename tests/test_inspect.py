"""The geometry report of `voxbake audit` (baker/scene/inspect.py):
duplicates dropped, coplanar overlaps, closed two-sided shells, two-sided
lamps."""
import numpy as np
import pytest

from baker.scene.inspect import coplanar_overlaps, geometry_report, two_sided_shells
from scenes.generate import icosphere, quad, scan_room


def tri(*p):
    return np.array(p, float)


def test_coplanar_overlap_facing_the_same_way_is_found_with_its_area():
    a = tri((0, 0, 0), (2, 0, 0), (0, 2, 0))        # area 2, facing +z
    b = tri((0, 0, 0), (1, 0, 0), (0, 1, 0))        # inside a: overlap 0.5
    pairs, area = coplanar_overlaps(np.stack([a, b]))
    assert pairs == 1 and area == pytest.approx(0.5)


@pytest.mark.parametrize("other,why", [
    (tri((0, 0, 0), (0, 1, 0), (1, 0, 0)), "the other face (a sheet): not a duplicate"),
    (tri((2, 2, 0), (3, 2, 0), (2, 3, 0)), "the same plane, apart"),
    (tri((0, 0, 0.01), (1, 0, 0.01), (0, 1, 0.01)), "a parallel plane"),
    (tri((2, 0, 0), (2, 2, 0), (0, 2, 0)), "sharing an edge only"),
])
def test_what_is_not_a_coplanar_overlap(other, why):
    a = tri((0, 0, 0), (2, 0, 0), (0, 2, 0))
    assert coplanar_overlaps(np.stack([a, other]))[0] == 0, why


def test_scan_room_reports_its_two_sided_shell(make_scene):
    scene = make_scene(scan_room(), "inspect_scan_room")
    report = geometry_report(scene)
    assert report.two_sided_shells == 1 and report.two_sided_shell_triangles == 17702
    assert report.duplicates_dropped == 0 and report.overlapping_pairs == 0
    assert "two-sided shells" in report.summary()


def test_open_or_one_sided_surfaces_are_not_shells(make_scene):
    from baker.scene.gltf_write import GltfBuilder
    b = GltfBuilder()
    one = b.material("one", (0.5,) * 3)
    two = b.material("two", (0.5,) * 3, double_sided=True)
    b.mesh("ball", *icosphere(2, 0.3), one)                                    # closed but one-sided
    b.mesh("sheet", *quad((0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1), subdiv=4), two)  # two-sided but open
    assert two_sided_shells(make_scene(b, "inspect_open"))[0] == 0


def test_dropped_duplicates_are_counted():
    from baker import load_scene
    from .conftest import MCGUIRE_CORNELL, skip_without_shared
    skip_without_shared(MCGUIRE_CORNELL, "McGuire's Cornell box OBJ")
    path = MCGUIRE_CORNELL
    report = geometry_report(load_scene(path))
    assert report.duplicates_dropped == 4 and "4 duplicate triangles dropped" in report.summary()
    assert report.two_sided_emitters == 2 and "both faces emit" in report.summary()  # the lamp, read two-sided
    assert geometry_report(load_scene(path, one_sided=True)).two_sided_emitters == 0


def _floor_scene(make_scene, name, second, lamp=False, two_sided_first=False):
    """A 2 x 2 floor quad facing up and a second quad in its plane
    (corners `second`, subdivided 3 x 3 so no triangle repeats the first's)."""
    from baker.scene.gltf_write import GltfBuilder
    b = GltfBuilder()
    floor = b.material("floor", (0.5,) * 3, double_sided=two_sided_first)
    other = b.material("other", (0.8,) * 3, emission=(2.0,) * 3 if lamp else (0.0,) * 3)
    b.mesh("floor", *quad((0, 0, 0), (2, 0, 0), (2, 0, 2), (0, 0, 2), facing=(0, 1, 0)), floor)
    b.mesh("other", *quad(*second, facing=(0, 1, 0), subdiv=3), other)
    b.light("sun", "directional", intensity=1.0, direction=(0, -1, 0))
    return make_scene(b, name)


def test_coplanar_overlap_is_cut_at_loading_and_counts_once(make_scene):
    """A second tiling over half of a floor: the loader cuts the covered
    part out of the later one (file order), so the union counts once: in
    the triangles' area, the audit and the voxels."""
    from baker.voxels.voxelize import voxelize
    scene = _floor_scene(make_scene, "overlap_half", ((1, 0, 1), (3, 0, 1), (3, 0, 3), (1, 0, 3)))
    assert any("overlapping part out of 8 coplanar triangles" in w for w in scene.warnings), scene.warnings
    c = scene.triangle_corners()
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])
    assert (n[:, 1] > 0).all()                                     # every piece still faces up
    assert scene.triangle_areas().sum() == pytest.approx(4 + 4 - 1, rel=1e-6)
    assert coplanar_overlaps(c)[0] == 0
    report = geometry_report(scene)
    assert report.overlaps_cut == 8 and "cut out of them when loading" in report.summary()
    other = scene.material_ids == 1
    assert scene.triangle_areas()[other].sum() == pytest.approx(3, rel=1e-6)   # the floor, first, stays whole
    vox = voxelize(scene, resolution=12)
    assert vox.area.sum() == pytest.approx(7, rel=1e-5)


def test_cut_pieces_interpolate_the_corners_attributes():
    """The new corners lie on their triangle's plane, and their normals and
    texture coordinates are the original's, interpolated."""
    from baker.scene.overlaps import cut_overlaps
    v = np.array([[0, 0, 0], [2, 0, 0], [2, 0, 2], [0, 0, 2], [1, 0, 1], [3, 0, 1], [3, 0, 3], [1, 0, 3]], float)
    t = np.array([[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]])
    uv = v[:, [0, 2]] * 0.3 + 0.1                                  # a linear map of the plane
    nrm = np.tile([0.0, 1.0, 0.0], (8, 1))
    v2, t2, m2, n2, uv2, (cut, area, whole) = cut_overlaps(v, t, np.array([0, 0, 1, 1]), np.zeros(2, bool),
                                                           np.zeros(2, bool), nrm, uv)
    assert cut == 2 and area == pytest.approx(1.0) and whole == 0
    assert np.abs(v2[:, 1]).max() == 0
    assert np.allclose(uv2, v2[:, [0, 2]] * 0.3 + 0.1) and np.allclose(n2, [0, 1, 0])
    assert (np.cross(v2[t2][:, 1] - v2[t2][:, 0], v2[t2][:, 2] - v2[t2][:, 0])[:, 1] > 0).all()


def test_pieces_grow_only_where_coverers_overlap():
    """A floor triangle under many small coverers (pot bases on a floor):
    each coverer splits only the pieces it overlaps, so the pieces grow
    with the coverers, not three-fold per coverer; past MAX_PIECES the
    triangle is kept whole and counted."""
    from baker.scene import overlaps
    n = 40
    floor = np.array([[0, 0, 0], [0, 0, 100], [100, 0, 0]], float)  # one-sided, facing +y
    xs = 1 + 2.2 * np.arange(n)
    small = [[[x, 0, 1], [x, 0, 2], [x + 1, 0, 1]] for x in xs]   # each a one-sided coverer inside the floor
    v = np.concatenate([np.concatenate(small), floor]).reshape(-1, 3)
    t = np.arange(len(v)).reshape(-1, 3)
    mids = np.zeros(len(t), np.int64)
    v2, t2, m2, _, _, (cut, area, whole) = overlaps.cut_overlaps(v, t, mids, np.zeros(1, bool), np.zeros(1, bool))
    assert cut == 1 and whole == 0 and area == pytest.approx(n * 0.5)
    assert len(t2) - n < 6 * n  # the floor's pieces: a few per coverer (before: 3^n)
    c = v2[t2]
    total = 0.5 * np.linalg.norm(np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0]), axis=1).sum()
    assert total == pytest.approx(5000.0)  # the floor's area, counted once
    old = overlaps.MAX_PIECES
    try:
        overlaps.MAX_PIECES = 8
        *_, (cut, area, whole) = overlaps.cut_overlaps(v, t, mids, np.zeros(1, bool), np.zeros(1, bool))
    finally:
        overlaps.MAX_PIECES = old
    assert cut == 0 and whole == 1


def test_lamp_on_the_ceilings_plane_stays_whole(make_scene):
    """An emitter ranks first: the surface it lies on loses its area, the
    lamp emits from all of it, once."""
    scene = _floor_scene(make_scene, "overlap_lamp", ((0.5, 0, 0.5), (1.5, 0, 0.5), (1.5, 0, 1.5), (0.5, 0, 1.5)),
                         lamp=True)
    lamp = scene.material_ids == 1
    assert scene.triangle_areas()[lamp].sum() == pytest.approx(1.0, rel=1e-6)
    assert scene.triangle_areas()[~lamp].sum() == pytest.approx(3.0, rel=1e-6)
    assert scene.emitted_power() == pytest.approx(np.pi * 2.0 * 1.0, rel=1e-6)


def test_one_sided_lamp_on_a_two_sided_surface_is_left_and_reported(make_scene):
    """A two-sided surface covers both faces of a one-sided tiling in its
    plane and cuts it. A one-sided lamp ranks first but covers only one
    face of a two-sided ceiling: cutting either would lose a face, so both
    stay and the audit reports the overlap."""
    corners = ((1, 0, 1), (3, 0, 1), (3, 0, 3), (1, 0, 3))
    cut = _floor_scene(make_scene, "overlap_sided", corners, two_sided_first=True)
    assert cut.triangle_areas().sum() == pytest.approx(7, rel=1e-6)
    scene = _floor_scene(make_scene, "overlap_sided_lamp", corners, lamp=True, two_sided_first=True)
    assert not any("coplanar" in w for w in scene.warnings)
    report = geometry_report(scene)
    assert report.overlapping_pairs > 0 and report.overlap_area == pytest.approx(1.0, rel=1e-6)
    assert "one-sided triangle over a two-sided one" in report.summary()
