import numpy as np
import pytest

from baker.scene import bvh as bvh_mod
from baker.scene import surfaces
from baker.solve.audit import audit, discrete_sources
from baker.solve.directions import direction_set
from baker.solve.propagate import LineSweeper
from baker.voxels import voxelize
from scenes.generate import closed_box, furnace_box, furnace_obstacles, scan_room, thin_wall, two_rooms
from tests.naive import line_inputs, propagate_lines


def test_discrete_sources_recover_the_voxel_seen(make_scene):
    """The index trick (radiosity = index + 1) gives the voxel each voxel
    gathered from: checked against the slow reference's trace."""
    v = voxelize(make_scene(furnace_obstacles(), "audit_obs"), 8)
    sw = LineSweeper(v)
    d = direction_set(2)
    f = 3
    src, sgn, s = discrete_sources(sw, d, f)
    one = (d.vectors[f:f + 1], d.axis[f:f + 1], d.unit[f:f + 1], d.solid_angle[f:f + 1] / np.pi)
    off = sw.offsets(d, 0, 2)[f:f + 1]
    ref = line_inputs(v)
    for x in np.nonzero(s > 0)[0][:40]:
        _, _, trace = propagate_lines(v.cell, np.zeros(3), ref["centroid"], ref["normal"], np.ones((len(v), 3)),
                                      *one, off, 1.0, trace=int(x), cut=ref["cut"], sheet=ref["sheet"],
                                      flat=ref["flat"], edge=ref["edge"], foot=ref["foot"])
        seen = [y for _, _, y in trace]
        assert (src[x] == -1 and not seen) or [src[x]] == seen


@pytest.mark.parametrize("name,builder", [("furnace", furnace_box), ("obstacles", furnace_obstacles),
                                          ("rooms", two_rooms), ("thin_wall", thin_wall),
                                          ("closed_box", closed_box), ("scan_room", scan_room)])
def test_lines_rarely_see_through_occluders(make_scene, name, builder):
    """Leak-like disagreement (the digital line sees beyond the first surface
    a continuous ray hits): measured 0-0.08% (cos-weighted) at 64 cells,
    0.09% on the scan-like two-sided shell (0.04% before the silhouette and
    edge clauses); bound 0.3%."""
    scene = make_scene(builder(), f"audit_{name}")
    report = audit(scene, voxelize(scene, 64), bvh_mod.build_scene_bvh(scene), surfaces.pack(scene), samples=1500)
    assert report.pairs > 10_000
    assert report.sees_through < 0.003
    assert report.other_surface < 0.003
