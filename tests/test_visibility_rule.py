"""The visibility rule clause by clause, on hand-built lines of a few voxels
(docs/design.md section 4). Each line runs along +x through cells 0..4
(y = z = 0, cell size 1); one family, s = (1, 0, 0). `seen` tells which
voxel each one's ray met (or -1). Each clause of the rule is missed by
some test here when it is turned off (tests/test_clauses.py runs them with
each clause off in turn)."""
import dataclasses
from dataclasses import dataclass, field

import numpy as np
import pytest

from baker.solve.directions import DirectionSet
from baker.solve.propagate import LineSweeper


@dataclass(frozen=True)
class Line:
    """The fields of Voxels that the propagation reads."""
    cell: np.ndarray
    centroid: np.ndarray
    normal: np.ndarray
    two_sided: np.ndarray
    cut_sign: np.ndarray
    cut_plane: np.ndarray
    planar: np.ndarray
    area: np.ndarray          # cells^2 (the cell size is 1): under 0.9 of the plane's cross-section of the cell, the
    #                           surface ends in the cell (voxels/edges.py); a voxel covers its cell unless told
    origin: np.ndarray = field(default_factory=lambda: np.zeros(3))
    cell_size: float = 1.0

    def __len__(self):
        return len(self.cell)

    @property
    def dims(self):
        return self.cell.max(axis=0).astype(np.int64) + 2

    @property
    def key(self):
        d = self.dims
        return (self.cell[:, 0].astype(np.int64) * d[1] + self.cell[:, 1]) * d[2] + self.cell[:, 2]


def line(*voxels):
    """voxels: dicts with x (centroid along the line), y (default 0.5),
    n (normal, normalised here), sheet (bool), cut (plane normal, plane
    offset n . g, side +1/-1) and flat (bool: planar, and flat when its
    neighbours on the line lie on its plane), area (cells^2, default: its
    whole cross-section of the cell). Cells follow from the centroids; the order
    given is the voxel order (a cell's voxels must be adjacent)."""
    c = np.array([[v["x"], v.get("y", 0.5), 0.5] for v in voxels])
    n = np.array([v["n"] for v in voxels], float)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    cell = np.floor(c).astype(np.int32)
    sign = np.array([v.get("cut", (None, None, 0))[2] for v in voxels], np.int8)
    plane = np.zeros((len(voxels), 4), np.float32)
    for i, v in enumerate(voxels):
        if "cut" in v:
            pn, off, _ = v["cut"]
            pn = np.asarray(pn, float) / np.linalg.norm(pn)
            plane[i, :3] = pn
            plane[i, 3] = off - pn @ cell[i]  # relative to the voxel's cell, as Voxels stores it
    keys = [tuple(x) for x in cell]
    assert all(keys[i] <= keys[i + 1] for i in range(len(keys) - 1)), "voxels must come in x-major cell order"
    return Line(cell, c, n, np.array([v.get("sheet", False) for v in voxels]), sign, plane,
                np.array([v.get("flat", False) for v in voxels]), np.array([v.get("area", 10.0) for v in voxels]))


ALONG_X = DirectionSet(1, np.array([[1, 0, 0]], np.int32), np.array([0], np.int32), np.array([[1.0, 0, 0]]),
                       np.array([0.5]))


def seen(vox):
    """(n,) int: the voxel each voxel's ray met along +x or -x (whichever
    its front faces), -1 for none. Radiosity = index + 1, so gathered / S
    is the index of the voxel met, plus one."""
    sw = LineSweeper(vox)
    rad = np.zeros((len(vox), 3))
    rad[:, 0] = np.arange(1, len(vox) + 1)
    g, s = sw.gather(rad, ALONG_X, np.zeros((1, 2), np.int64))
    out = np.full(len(vox), -1)
    ok = s > 0
    out[ok] = np.rint(g[ok, 0] / s[ok]).astype(int) - 1
    return out


PLUS, MINUS = (1, 0, 0), (-1, 0, 0)   # facing +s (sends a ray along it) / facing -s (receives it)


def test_front_gathers():
    """A voxel facing the rays is gathered by the waiting voxel in front of
    it, and the two see each other."""
    a, b = 0, 1
    s = seen(line(dict(x=0.5, n=PLUS), dict(x=3.5, n=MINUS)))
    assert s[a] == b and s[b] == a


def test_behind_keeps_waiting():
    """A voxel facing the rays whose plane the waiting voxel lies behind
    (beyond tau) is not seen: the ray moves away from its plane and goes on
    to the next voxel facing it."""
    vox = line(dict(x=0.5, y=0.1, n=PLUS),
               dict(x=2.5, y=0.9, n=(-0.3, 1, 0)),   # faces -x a little; the first voxel is 0.19 behind its plane
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == 2


def test_back_blocks():
    """A voxel turning its back to the rays, with the waiting voxel behind
    its plane, stops that ray: it gathers nothing. The blocker then waits
    and sees what is beyond."""
    s = seen(line(dict(x=0.5, n=PLUS), dict(x=2.5, n=PLUS), dict(x=4.5, n=MINUS)))
    assert s[0] == -1 and s[1] == 2


def test_convex_edge_does_not_block():
    """The waiting voxel on a box's top near its edge and the next voxel on
    the box's side just below form a convex edge (each just behind the
    other's plane, within kappa): the side's back does not stop the top's
    ray, which goes on over the edge."""
    vox = line(dict(x=0.5, y=0.8, n=(0.2, 1, 0)),   # the top, tilted a little towards +x: it sends along +x
               dict(x=1.4, y=0.3, n=PLUS),          # the side below the edge, turning its back to the ray
               dict(x=4.5, n=MINUS))
    s = seen(vox)
    assert s[0] == 2 and s[1] == 2


@pytest.mark.parametrize("curved", [True, False])
def test_ray_past_a_convex_silhouette_goes_on(curved):
    """A voxel of a curved surface turning its back to the rays, the waiting
    voxel behind its plane, but the waiting voxel's ray, level with it,
    0.33 cells in front of its tangent plane: the ray crossed that plane
    before and passes the surface by (a scan's silhouette seen by a line a
    cell thick), so it goes on to the voxel beyond. A flat voxel in the same
    place blocks the ray (a ray cannot pass a plane twice). Without the
    clause the curved voxel blocks it too: a closed scan-like shell lost 2%
    of its own light this way (tests/test_propagate.py)."""
    vox = line(dict(x=0.5, n=PLUS),
               dict(x=2.5, y=0.1, n=(1, 1.5, 0), flat=not curved),  # faces +x and up: the far side of a bump
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == (2 if curved else -1)


def test_ray_behind_a_curved_back_is_blocked():
    """The same voxel tilted the other way (faces +x and down): the ray,
    level with it, is 0.33 cells behind its plane and meets its back."""
    vox = line(dict(x=0.5, n=PLUS), dict(x=2.5, y=0.1, n=(1, -1.5, 0)), dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == -1


@pytest.mark.parametrize("beside", [True, False])
def test_ray_past_the_edge_of_a_surface_goes_on(beside):
    """y, facing the rays, is the last piece of a surface that ends inside
    its cell: it rises 0.3 of the way up the cell (area 0.3 of the plane's
    cross-section; the edge of a box's face). x, beside the surface (above
    its edge line), sends a ray that meets y's plane above the edge: it
    passes y and meets the voxel beyond. The same ray from over the surface
    (x's centroid inside the edge's half-plane, 0.25 up) gathers y: passing
    there let light run down a body's side."""
    top = dict(x=2.5, y=0.15, n=(-1, -0.2, 0), area=0.3, flat=True)  # faces the ray, tilted a little
    x = dict(x=0.5, y=0.9, n=PLUS) if beside else dict(x=0.5, y=0.25, n=PLUS)
    vox = line(x, top, dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == (2 if beside else 1)


@pytest.mark.parametrize("back", [False, True])
def test_ray_past_a_small_piece_goes_on(back):
    """y is a small piece in the middle of its cell (area 0.04 of the
    cross-section: a frame's moulding, a chandelier's arm), facing the ray
    or turning its back to it; x's ray runs 0.4 cells beside its centre,
    further than its footprint's radius (1.3 x that of a disc of its area,
    0.15): it passes y and meets the wall beyond. A line a cell thick
    stopped there: a wall behind a painting's frame saw a fifth of the light
    rays from it see."""
    piece = dict(x=2.5, n=PLUS if back else MINUS, area=0.04, flat=True)
    vox = line(dict(x=0.5, y=0.9, n=PLUS), piece, dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == 2


def test_small_piece_passed_is_gathered_when_nothing_lies_beyond():
    """The same ray past the small piece then meets only a back: it gathers
    the piece it passed (its fallback), not nothing. The footprint is a
    disc; a closed curved sheet's piece clipping a cell's corner is not,
    and a ray let past it would run out through the sheet between its
    cells (a double-sided furnace sphere lost 1.5%)."""
    vox = line(dict(x=0.5, y=0.9, n=PLUS), dict(x=2.5, n=MINUS, area=0.04, flat=True), dict(x=4.5, n=PLUS))
    assert seen(vox)[0] == 1


def test_tie_puts_the_sender_first():
    """Two voxels at one centroid facing each other (a box resting on a
    floor): the one sending along the ray comes first, so it meets the
    other instead of passing it; given in the other order here."""
    vox = line(dict(x=0.5, n=PLUS),
               dict(x=2.5, n=MINUS),   # the box's bottom, listed first in its cell
               dict(x=2.5, n=PLUS),    # the floor at the same centroid
               dict(x=4.5, n=MINUS))
    s = seen(vox)
    assert s[2] == 1 and s[1] == 2  # floor and bottom see each other, not what lies beyond
    assert s[0] == -1  # behind the floor's plane: its back stops the first voxel's ray


def test_sheet_faces_back_to_back():
    """The two faces of a double-sided sheet at one centroid: each sees what
    is on its own side, never the other face."""
    vox = line(dict(x=0.5, n=PLUS),
               dict(x=2.5, n=PLUS, sheet=True),
               dict(x=2.5, n=MINUS, sheet=True),
               dict(x=4.5, n=MINUS))
    a, p, q, b = range(4)
    s = seen(vox)
    assert s[a] == q and s[q] == a and s[p] == b and s[b] == p


def test_sheet_face_does_not_see_its_other_face_in_the_next_cell():
    """A curved sheet's faces can fall into neighbouring cells of one line,
    within tau of each other's plane: a face does not see its own back."""
    vox = line(dict(x=0.5, n=PLUS),
               dict(x=2.95, n=PLUS, sheet=True),
               dict(x=3.02, n=MINUS, sheet=True),
               dict(x=4.5, n=MINUS))
    s = seen(vox)
    assert s[1] == 3


@pytest.mark.parametrize("sheet", [False, True])
def test_sheet_face_is_seen_from_in_front_only(sheet):
    """A waiting voxel just behind a face's plane (within tau) sees a
    one-sided face (the tau slack of a thick digital surface) but not a
    sheet's face: behind a sheet's face within tau lies its other face."""
    vox = line(dict(x=1.5, y=0.77, n=PLUS),
               dict(x=2.0, y=0.2, n=(-1, -1, 0), sheet=sheet),   # 0.05 in front of the first voxel's...
               dict(x=2.0, y=0.2, n=(1, 1, 0), sheet=sheet),     # ... position, seen from behind
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == (3 if sheet else 1)


def test_cut_voxel_is_hidden_across_its_cutting_surface():
    """A voxel whose pieces another surface's plane cut (a floor running
    under a wall at x = 3) is not seen from the wall's other side: the
    segment between them crosses that plane near the cut voxel."""
    cut = line(dict(x=0.5, n=PLUS), dict(x=4.5, n=MINUS, cut=((1, 0, 0), 3.0, 1)))
    assert seen(cut)[0] == -1
    whole = line(dict(x=0.5, n=PLUS), dict(x=4.5, n=MINUS))
    assert seen(whole)[0] == 1


def test_inner_face_of_a_convex_sheet_is_passed():
    """A convex two-sided surface curving away below the line (a scanned
    shell): the next cell holds both faces of the sheet; its inner face
    faces the ray, just behind the outer face's plane. The ray passes over
    the surface, as it passes the outer face's back (a convex edge), and
    meets what lies beyond, not the shell's dark inside."""
    vox = line(dict(x=0.5, n=(0.2, 1, 0), sheet=True),            # the outer face, sending along +x
               dict(x=1.5, y=0.2, n=(-0.5, -1, 0), sheet=True),   # the next cell: the inner face, facing the ray
               dict(x=1.5, y=0.2, n=(0.5, 1, 0), sheet=True),     # ... and the outer face, turning its back
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == 3


@pytest.mark.parametrize("heads_for_it", [False, True])
def test_cutting_surface_hides_only_what_the_ray_heads_for(heads_for_it):
    """A voxel cut by another surface's plane, and a voxel on that plane's
    other side a cell further on the same (cell-thick) line: the surface
    stands between them. When the ray moves away from the plane it never
    reaches its other side: the first voxel keeps waiting and meets the
    voxel beyond, on its own side; when the ray heads for the plane, the
    surface is in its way and it gathers nothing."""
    if heads_for_it:
        plane, farther = ((-1, 4, 0), 0.2, 1), -1
    else:
        plane, farther = ((1, 4, 0), 0.85, 1), 2
    vox = line(dict(x=0.5, y=0.9, n=PLUS, cut=plane),
               dict(x=2.5, y=0.1, n=MINUS),    # across the plane
               dict(x=4.5, y=0.5, n=MINUS))   # on the first voxel's side (moving away), or across as well
    assert seen(vox)[0] == farther


def test_inner_face_of_a_convex_sheet_is_passed_along_the_chain():
    """Further along the convex shell the inner face lies more than kappa
    in front of the waiting voxel's position: the outer face that joined
    the line last (z) and the sheet there form the convex edge instead."""
    vox = line(dict(x=0.5, y=0.95, n=(0.1, 1, 0), sheet=True),     # the waiting outer face
               dict(x=1.5, y=0.7, n=(-0.2, -1, 0), sheet=True),    # a cell on: inner face (x lies behind it) ...
               dict(x=1.5, y=0.7, n=(0.2, 1, 0), sheet=True),      # ... and outer face: joins the line (z)
               dict(x=3.5, y=0.0, n=(-1, -1, 0), sheet=True),      # further down the curve: inner face ...
               dict(x=3.5, y=0.0, n=(1, 1, 0), sheet=True),        # ... and outer face
               dict(x=5.5, n=MINUS))
    assert seen(vox)[0] == 5


def test_other_face_of_a_noisy_sheet_is_not_seen():
    """A noisy two-sided surface: in the next cell a face of the sheet faces
    the waiting face with a normal 45 degrees off opposite, within kappa
    of each other's plane (its pieces went to another facing). It is the
    surface's own other face: not seen."""
    vox = line(dict(x=0.5, n=PLUS, sheet=True),
               dict(x=1.4, y=0.9, n=(-0.7, 0.714, 0), sheet=True),
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == 2


def test_flat_junction_of_two_facings_does_not_block():
    """Two facings of one noisy surface meet in a cell: the next voxel turns
    its back to the ray, the waiting voxel lies behind its plane (within
    kappa) and it lies a little (within tau) in front of the waiting
    voxel's plane. A flat junction, not a wall: the ray goes on."""
    vox = line(dict(x=0.5, n=(0.2, 1, 0)),
               dict(x=1.3, y=0.38, n=(1, 0.3, 0)),
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == 2


def test_surface_that_cut_a_piece_passes_it_behind_its_plane():
    """A wall's foot (on the plane that cut the floor's piece in its cell)
    and the part of that piece under the wall, behind the wall's plane,
    which the line meets after it (a box's side and the floor under
    the box, ordered by centroid along a line a cell thick): the wall's ray
    moves away from it and meets what lies beyond, not nothing."""
    wall = ((1, 1, 0), 1.5 / np.sqrt(2), -1)  # the wall's plane through (1, 0.5), facing +x and +y
    vox = line(dict(x=1.0, n=(1, 1, 0)),                           # the wall's foot, on that plane
               dict(x=1.3, y=0.1, n=(-0.2, 1, 0), cut=wall),      # the cut part: behind it, after it on the line
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == 2


def floor_under_ray(ends_at=5):
    """A box's side (cell 0, at height 0.9) sending along +x over a floor
    tilted towards the ray (normal (-0.25, 1, 0)) whose plane the ray meets
    at x = 3.6 (cell 3), floor voxels in cells 1 .. ends_at - 1, and a wall
    facing the ray in cell 5."""
    n = np.array([-0.25, 1.0, 0.0]) / np.hypot(0.25, 1.0)
    p0 = np.array([3.6, 0.9, 0.5])  # where the ray from (0.5, 0.9) meets the floor's plane
    floor = [dict(x=x, y=float(p0[1] + 0.25 * (x - p0[0])), n=tuple(n), flat=True)
             for x in (1.5, 2.5, 3.5, 4.5)[:ends_at - 1]]
    return line(dict(x=0.5, y=0.9, n=PLUS), *floor, dict(x=5.5, n=MINUS))


def test_grazing_ray_gathers_a_flat_floor_where_it_meets_it():
    """The line meets the floor's voxels from cell 1 on, the ray its plane
    in cell 3: the gather lands there (the floor in a box's contact shadow,
    next to it, is not what a grazing ray from the box's foot sees). Not
    flat, the floor is gathered where the line meets it."""
    vox = floor_under_ray()
    assert seen(vox)[0] == 3
    assert seen(dataclasses.replace(vox, planar=np.zeros(len(vox), bool)))[0] == 1


def test_convex_edge_with_the_waiting_voxel_when_another_joined_since():
    """The top of a box near its edge waits; a voxel low on the box's side
    joins the line after it (the last added) and hits the back of the
    side's next voxel. The top and that voxel form the convex edge, not
    the last added: the top's ray goes on over the edge, the other's is
    stopped."""
    vox = line(dict(x=0.5, y=0.8, n=(0.2, 1, 0)),   # the top, sending along +x
               dict(x=1.1, y=0.1, n=PLUS),          # joins the line after it, far below the edge
               dict(x=1.4, y=0.3, n=PLUS),          # the side below the edge, turning its back
               dict(x=4.5, n=MINUS))
    s = seen(vox)
    assert s[0] == 3 and s[1] == -1


def test_convex_edge_with_the_voxel_last_added():
    """A voxel waiting level with a box's top, far behind the box: the top
    near its edge joins the line, and the side's voxel below the edge turns
    its back. The waiting voxel and the side form no edge (it is a cell
    behind it), but the top, the voxel last added, does: the ray passes
    over the edge."""
    vox = line(dict(x=0.5, y=0.95, n=PLUS),
               dict(x=1.2, y=0.8, n=(0.2, 1, 0)),   # the top near its edge: joins the line last
               dict(x=1.4, y=0.3, n=PLUS),          # the side, turning its back
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == 3


def test_a_surface_along_the_line_hides_what_lies_on_its_other_side():
    """The line, a cell thick, runs along a floor (its voxel parallel to the
    ray, at height 0.5 in cell 2): a waiting voxel above the floor does not
    see a voxel below it further on (the lid of a box looking down its wall
    does not see the floor outside)."""
    vox = line(dict(x=0.5, y=0.8, n=PLUS), dict(x=2.5, y=0.5, n=(0, 1, 0)), dict(x=4.5, y=0.2, n=MINUS))
    assert seen(vox)[0] == -1
    assert seen(line(dict(x=0.5, y=0.8, n=PLUS), dict(x=4.5, y=0.2, n=MINUS)))[0] == 1


def test_a_wall_standing_in_the_cell_separates_a_floor_beyond_it():
    """y, a floor piece tilted to face the ray a little, lies in the cell
    of a leaning wall but on its far side, and comes first in the cell
    along the line. The segment from the waiting voxel to y crosses the
    wall's plane inside the cell: the waiting voxel does not see y, keeps
    waiting (its ray meets the wall only beyond y) and gathers the wall."""
    vox = line(dict(x=0.5, y=0.8, n=PLUS),
               dict(x=2.45, y=0.05, n=(-0.2, 1, 0)),   # the floor beyond the wall
               dict(x=2.5, y=0.5, n=(-1, 0.5, 0)),     # the wall, leaning towards the ray
               dict(x=4.5, n=MINUS))
    assert seen(vox)[0] == 2


def test_a_back_beyond_a_cutting_surface_is_out_of_reach():
    """The waiting voxel was cut by another surface's plane; the next voxel
    on the line turns its back, on that plane's other side, and the ray
    moves away from the plane: the back is out of the ray's reach, the
    waiting voxel goes on to the voxel beyond, on its own side."""
    vox = line(dict(x=0.5, y=0.9, n=PLUS, cut=((1, 4, 0), 0.85, 1)),
               dict(x=2.5, y=0.1, n=PLUS),    # across the plane, turning its back
               dict(x=4.5, y=0.5, n=MINUS))
    assert seen(vox)[0] == 2
