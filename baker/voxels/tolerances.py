"""Named tolerances of the voxel geometry, one per concept, used by the
voxelization and by the propagation's visibility rule alike. Lengths and
areas in cells (grid units); cosines between unit normals.
"""

CLUTTER_VOXELS = 512     # a cell with more voxels than this merges its small ones by facing (voxelize.merge_clutter)
CLUTTER_PIECES = 64      # a cell with more pieces than this is cut only by its large ones (cells.find_straddlers)
CLUTTER_AREA = 0.25      # cells^2: a crowded cell's voxels at least this large keep to themselves
SHEET_GAP = 0.1          # pieces of one facing on planes further apart than this are separate voxels (sheets)
MIN_SPLIT_PART = 1e-6    # cells^2: a piece is cut by another surface's plane when both parts are larger
MIN_SEPARATION = 0.01    # pieces this far on both sides of a surface's plane are told apart by it
MIN_PIECE_AREA = 1e-14   # cells^2: below this a clipped piece is rounding noise (slivers above it are kept: a
#                          plane passing 1e-6 cell from a corner still separates the lines there)
SHEET_BACK_COS = -0.9    # normals this opposite (within 25 degrees) are the two faces of one double-sided
#                          surface, not one surface crossing the other: a curved sheet's faces in a cell can come
#                          from different triangles, and a digital line reaches its other face in the next cell
PARALLEL_COS = 0.9       # |cos| at least this: the planes are parallel (one does not cut or separate the other),
#                          and neighbouring voxels at least this aligned lie on the same surface
SMOOTH_COS = 0.7         # triangles sharing an edge with normals within 45 degrees are one smooth surface in a cell
#                          (a scan's or a fine tessellation's pieces; sharper creases are surfaces of their own)
SAME_PLANE_COS = 0.999   # |cos| above this, with offsets within tau: the same plane
FLAT_COS = 0.9999        # a voxel is flat when its pieces' normals, and those of the voxels of its surface in the 26
FLAT_PLANE = 0.02        # cells around it (normals within 45 degrees, SMOOTH_COS), agree within this cosine (0.8
#                          degrees) and their centroids lie within FLAT_PLANE cells of its plane: a floor, a wall, a
#                          box's face; not a tessellated sphere or a scan (the propagation defers a grazing ray's
#                          gather on a flat voxel to where the ray meets its plane, visibility.py)
GRID_SNAP = 1e-6         # cells: a triangle corner this close to a cell boundary lies on it (voxels.clip.to_grid)
SKIN_COS = 0.5           # a surface met from behind just over a curved voxel's centroid, its normal within 60 degrees
#                          of the voxel's, is the voxel's own surface (its skin): the centroid lies under it by the
#                          sagitta of the voxel's patch (lights.vpl.on_surface, solve.gather)
BURIED_SAMPLES = 3       # a piece's buried share is measured at BURIED_SAMPLES^2 of its points (voxels.buried)
BURIED_RAYS = 16         # rays per point
BURIED_BACK = 0.6        # a point is buried when this share of its rays meet a triangle from behind ...
BURIED_NEAR = 0.25       # ... and this share a one-sided one, or a two-sided one within BURIED_REACH cells
BURIED_REACH = 2.0       # (the texels' inside test: lightmap/texels.inside_geometry)
BURIED_FLOOR = 0.02      # the weight of a wholly buried piece (never 0: a voxel keeps an area)
BURIED_KEEP = 0.25       # a voxel keeps at least this share of its area (its irradiance grows at most 4x)
