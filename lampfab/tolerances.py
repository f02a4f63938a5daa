"""Every numerical tolerance lampfab uses, with the reason for its value."""

# Vertices closer than this are the same vertex when a mesh from a file is welded:
# Blender exports split vertices along UV/normal seams at identical positions, and
# 1 µm is far below any feature a printer (25 µm layers) or a mill can make.
WELD_MM = 1e-3

# Two volumes (STL vs STEP) must agree to this relative tolerance (issue: 0.5 %).
VOLUME_REL = 5e-3

# Target for the B-spline's deviation from the heightmap surface: well below a
# polishing pass (~10 µm) so the STEP and the STL describe the same part.
BSPLINE_DEVIATION_MM = 5e-3

# Rays leave a surface offset by this much along the ray to avoid self-hits; the lens
# is ~1e2 mm across, so 1e-4 mm is ~1e-6 relative, well above float32 rounding at 1e2.
RAY_EPSILON_MM = 1e-4

# A heightmap may not bring the outer surface closer than this to the inner layer
# during optimization even before the fabrication check (keeps the solid valid).
MIN_GAP_MM = 0.5

# Targets whose luminance range (max - min) is below this are "constant": nothing to
# project.  Linear luminance in [0, 1]; 1e-3 is about one 8-bit step in sRGB shadows.
CONSTANT_TARGET_RANGE = 1e-3

# verify's render of the exported STL must match the optimizer's own final render of the
# lens to at least this Pearson r on every wall (issue: "verify of the exported STL
# matches the optimizer's own final render"); below it the file is not the lens that
# was optimized (a wrong export, or a tracer disagreement worth a look).
OPTIMIZER_MATCH_R = 0.98
