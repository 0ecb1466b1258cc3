#!/usr/bin/env bash
# The 1996 color-cube paper's Figure 5 on our machine: render time against
# scene size, geometry and hierarchy, for gen:forest with 1, 4, 16, ... trees
# (each tree 50 000 triangles), with the log-log slopes fitted.
# Usage: benches/cubes_figure5.sh [MAX_TREES] [SIZE]   (default 256, 256x256)
set -euo pipefail
cd "$(dirname "$0")/.."
max=${1:-256}
size=${2:-256x256}
out=$(mktemp -d)
cargo build --release -q -p farfield-server -p farfield-cli
server=target/release/farfield-server
client=target/release/farfield
echo "trees triangles geometry_ms hierarchy_ms speedup faces hierarchy_triangles psnr_db build_s file_bytes"
n=1
while [ "$n" -le "$max" ]; do
  f="$out/forest$n.ff"
  build=$($server build gen:forest --param trees=$n --kind cubes --out "$f" --json)
  row=$($client bench-cubes --file "$f" --input gen:forest --param trees=$n \
        --distances 1.5 --azimuth 30 --elevation 30 --size "$size" --repeats 3 --json 2>/dev/null)
  python3 - "$n" "$build" "$row" <<'PY'
import json, sys
n, build, row = sys.argv[1], json.loads(sys.argv[2]), json.loads(sys.argv[3])
r = row["rows"][0]
print(n, r["reference_triangles"], round(r["geometry"]["median_ms"], 2), round(r["hierarchy"]["median_ms"], 2),
      round(r["speedup"], 2), r["cube_faces"], r["triangles_drawn"],
      "inf" if r["psnr_db"] is None else round(r["psnr_db"], 2), round(build["seconds"], 1), build["file_bytes"])
PY
  rm -f "$f"
  n=$((n * 4))
done | tee "$out/table.txt"
# Least-squares slope of log(time) against log(triangles), per column.
awk 'function fit(col,   i, sx, sy, sxx, sxy, k, x, y) {
       for (i = 1; i <= NR; i++) { x = log(t[i]); y = log(v[col, i]); sx += x; sy += y; sxx += x*x; sxy += x*y; k++ }
       return (k * sxy - sx * sy) / (k * sxx - sx * sx) }
     { t[NR] = $2; v[3, NR] = $3; v[4, NR] = $4 }
     END { printf "log-log slope of time against triangles: geometry %.3f, hierarchy %.3f\n", fit(3), fit(4) }' "$out/table.txt"
rm -rf "$out"
