#!/usr/bin/env bash
# The thesis's demonstration (Section 7.2) through the geotraj CLI: the key frames of
# Table 7.8 with the curvature and torsion of Table 7.18 (paths A, B, C), tangent scale
# 0.25. For each path: the arc length of every segment and the geometry achieved at every
# key frame; then figures of the three paths and their curvature and torsion under out/
# (scripts/geotraj_plot.py, matplotlib); then the speed tables
# (Tables 7.21, 7.22) with their plots (scripts/motion_demo.py); then the paths on the PA-10
# in joint space at 10 s and time-optimal (scripts/robot_demo.py); then the optimisers:
# tangent scales (SVG before/after) and Appendix B.3's breakpoint table.
#   usage: scripts/demo.sh [BUILD_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
build="${1:-build}"
cli="$build/client/geotraj"
requests=client/grpcurl
out=out
mkdir -p "$out"

[ -x "$cli" ] || { echo "demo: $cli is missing; run 'make build' first" >&2; exit 1; }

for path in a b c; do
  P=$(echo "$path" | tr a-c A-C)
  echo
  echo "=== Thesis demonstration, path $P (Tables 7.8 and 7.18)"
  "$cli" plan "$requests/plan_demo_path_$path.json"
  # The profile for the picture: 600 points along the path.
  /usr/bin/python3 scripts/request_with.py "$requests/plan_demo_path_$path.json" "$out/request_$path.json" \
    analysisPoints=600
  "$cli" --json analyze "$out/request_$path.json" > "$out/profile_$path.json"
  "$cli" --json plan "$out/request_$path.json" > "$out/plan_$path.json"   # its warnings, for the figures
done

# Figures (scripts/geotraj_plot.py, matplotlib): the paths, and their curvature and torsion.
/usr/bin/python3 scripts/plot_paths.py "$out/thesis_paths.svg" --geometry "$out/thesis_geometry.svg" \
  --title "The thesis's demonstration: paths A, B, C (Tables 7.8, 7.18)" \
  "path A (kappa2 5, tau2 -50; kappa3 1, tau3 0)=$out/request_a.json:$out/profile_a.json:$out/plan_a.json" \
  "path B (kappa2 10, tau2 -50; kappa3 10, tau3 100)=$out/request_b.json:$out/profile_b.json:$out/plan_b.json" \
  "path C (kappa2 20, tau2 -50; kappa3 10, tau3 -100)=$out/request_c.json:$out/profile_c.json:$out/plan_c.json"
echo
echo "Wrote $out/thesis_paths.svg (3-D, top and side views of paths A, B, C in metres; key frames numbered from 0, the cusp in orange)"
echo "Wrote $out/thesis_geometry.svg (curvature, torsion and their derivatives along the arc length)"

# The speed along the path (Tables 7.21 and 7.22): measured as the thesis does, against the
# profile, for TAYLOR_SECOND_ORDER and ARC_LENGTH timing; SVG plots under out/.
/usr/bin/python3 scripts/motion_demo.py "$cli" "$out"

# The same paths on the PA-10 in joint space (thesis 6.4, 7.2): limit margins, IK
# residuals, manipulability, and SVG plots of the joints.
/usr/bin/python3 scripts/robot_demo.py "$cli" "$out"

# The three readings of unspecified constraints side by side (peak curvature between the
# frames, length, peak speed, the PA-10's limit usage at 10 s, the time-optimal duration).
/usr/bin/python3 scripts/readings_demo.py "$cli"
for reading in smoothest thesis_zeros lowest_degree; do
  /usr/bin/python3 scripts/request_with.py "$out/request_c.json" "$out/request_c_$reading.json" \
    "path.unspecified=UNSPECIFIED_CONSTRAINTS_${reading^^}"
  "$cli" --json analyze "$out/request_c_$reading.json" > "$out/profile_c_$reading.json"
done
/usr/bin/python3 scripts/plot_paths.py "$out/readings_path_c.svg" --geometry "$out/readings_geometry_c.svg" \
  --title "Path C under the three readings of unspecified constraints" \
  "path C, SMOOTHEST (the default)=$out/request_c_smoothest.json:$out/profile_c_smoothest.json" \
  "path C, THESIS_ZEROS=$out/request_c_thesis_zeros.json:$out/profile_c_thesis_zeros.json" \
  "path C, LOWEST_DEGREE=$out/request_c_lowest_degree.json:$out/profile_c_lowest_degree.json"
echo "Wrote $out/readings_path_c.svg and $out/readings_geometry_c.svg (path C under the three readings of unspecified constraints)"

# A path of pieces (thesis 2.4, 4.4): the weld seam with G4 transitions within 0.1 mm.
echo
echo "=== A path of pieces: a weld seam (line, quarter arc, line) on the UR5e, transitions within 0.1 mm"
"$cli" plan client/grpcurl/plan_seam_ur5e.json | sed -n '1,7p;/^motion/p'
/usr/bin/python3 scripts/plot_seam.py "$cli" client/grpcurl/plan_seam_ur5e.json "$out/seam_curvature.png"
echo "Wrote $out/seam_curvature.png (the seam's top view and curvature, with and without its transitions)"

# Optimisation: the tangent scales of path A chosen for the least
# bending energy (the thesis's 0.25 against the optimised ones, SVG), and Appendix B.3's
# breakpoint table (uniform, the thesis's hand-tuned B.11 and B.13, optimised).
echo
echo "=== Tangent scales of path A (the default reading): the thesis's 0.25 at every frame against the optimised ones"
# Bending energy plus the default length weight E0 / L0 times the length: without the length
# term the least bent curve through these frames is a long loop.
/usr/bin/python3 scripts/request_with.py "$out/request_a.json" "$out/request_a_optimised.json" \
  'optimize={"tangentScales": {"objective": "TANGENT_SCALE_OBJECTIVE_BENDING_ENERGY"}}'
"$cli" plan "$out/request_a_optimised.json" | sed -n '/^optimisation/,$p'
"$cli" --json analyze "$out/request_a_optimised.json" > "$out/profile_a_optimised.json"
/usr/bin/python3 scripts/plot_paths.py "$out/tangent_scales_path_a.svg" --geometry "$out/tangent_scales_geometry_a.svg" \
  --title "Path A: the thesis's tangent scales against the optimised ones" \
  "path A, tangent scale 0.25 (thesis)=$out/request_a.json:$out/profile_a.json" \
  "path A, tangent scales for the least bending energy + E0/L0 x length=$out/request_a.json:$out/profile_a_optimised.json"
echo "Wrote $out/tangent_scales_path_a.svg"
echo
echo "=== Appendix B.3 (Table B.1's path): peak torsion and curvature by breakpoints"
/usr/bin/python3 scripts/appendix_b_table.py "$cli"
