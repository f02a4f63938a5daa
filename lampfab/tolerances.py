"""Every numerical tolerance lampfab uses, with the reason for its value."""

# Vertices closer than this are the same vertex when a mesh from a file is welded:
# Blender exports split vertices along UV/normal seams at identical positions, and
# 1 µm is far below any feature a printer (25 µm layers) or a mill can make.
WELD_MM = 1e-3

# Two volumes (STL vs STEP) must agree to this relative tolerance (issue: 0.5 %).
VOLUME_REL = 5e-3

# Relative tolerance of the solid's volume bookkeeping (outer - cavity = solid, mesh
# volume = manifold3d's): its booleans are exact up to float64 rounding of the new
# vertices (~1e-12 relative here).
MANIFOLD_VOLUME_REL = 1e-7

# Tolerance of the face/edge geometry handed to OCCT (its Precision::Confusion).
OCC_TOLERANCE_MM = 1e-7

# A facet's vertices must lie this close to its plane to become one planar STEP face (a
# tenth of the edge tolerance, so its straight edges lie on the plane); otherwise its
# triangles become faces of their own.  Axis-aligned faces are exact; tilted quads from
# a float32 file usually fall back to their two triangles.
PLANAR_MM = 0.1 * OCC_TOLERANCE_MM

# Relative accuracy asked of OCCT's adaptive volume integration.  Its default (fixed
# Gauss points) was 1.3 % off on a rough 256 x 64 lens; 1e-5 lands within ~1e-5 of the
# converged value in 0.2 s, 1e-6 takes 7x longer for a digit the 0.5 % check never needs.
OCC_VOLUME_REL = 1e-5

# STEP edges built from the same curves or points coincide to float rounding (~1e-12
# mm); edges this close are the same edge when the panel's faces are sewn, or when a
# periodic face's boundary is picked by its height.  Distinct edges lie 1 mm or more
# apart, so 1e-6 mm tells them apart with room either way.
OCC_COINCIDENT_MM = 1e-6

# Target for the B-spline's deviation from the heightmap surface: well below a
# polishing pass (~10 µm) so the STEP and the STL describe the same part.
BSPLINE_DEVIATION_MM = 5e-3

# Rays leave a surface offset by this much along the ray to avoid self-hits; the lens
# is ~1e2 mm across, so 1e-4 mm is ~1e-6 relative, well above float32 rounding at 1e2.
RAY_EPSILON_MM = 1e-4

# The facet walk (``facetwalk``) takes a facet as holding a ray's hit when its
# barycentric weights are all above minus this: float32 rounding of the weights of a
# hit on an edge is ~1e-7, and a hit 1e-6 of a facet outside it (~0.3 nm on the
# default's facets) lands where the neighbour's plane would put it.
FACET_WALK_BARYCENTRIC = 1e-6

# A heightmap may not bring the outer surface closer than this to the inner layer
# during optimization even before the fabrication check (keeps the solid valid).
MIN_GAP_MM = 0.5

# Targets whose luminance range (max - min) is below this are "constant": nothing to
# project.  Linear luminance in [0, 1]; 1e-3 is about one 8-bit step in sRGB shadows.
CONSTANT_TARGET_RANGE = 1e-3

# A face designed at exactly the overhang limit must pass despite rounding in its
# normals (float64 cross products of mm coordinates: ~1e-12 deg).
ANGLE_TOL_DEG = 1e-6

# verify's render of the exported STL must match the optimizer's own final render of the
# lens to at least this Pearson r on every wall (issue: "verify of the exported STL
# matches the optimizer's own final render"); below it the file is not the lens that
# was optimized (a wrong export, or a tracer disagreement worth a look).
OPTIMIZER_MATCH_R = 0.98

# A lens's top and base (``paint``): facets within this tilt of horizontal, and this
# close to z = 0 or to the lens's height.  The outer surface tilts 68° at most (the
# steepest slope limit), and the flat faces are exact planes, so any value from a
# thousandth of a degree to 20° picks the same facets; 8° leaves room both ways.
FLAT_FACE_DEG = 8.0
FLAT_FACE_HEIGHT_MM = 1e-3
