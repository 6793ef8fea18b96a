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
    import os
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    from baker import load_scene
    path = os.path.join(here, "scenes", "cornell_box_original.obj")
    report = geometry_report(load_scene(path))
    assert report.duplicates_dropped == 4 and "4 duplicate triangles dropped" in report.summary()
    assert report.two_sided_emitters == 2 and "both faces emit" in report.summary()  # the lamp, read two-sided
    assert geometry_report(load_scene(path, one_sided=True)).two_sided_emitters == 0
