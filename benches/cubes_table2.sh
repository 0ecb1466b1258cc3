#!/usr/bin/env bash
# The 1996 color-cube paper's Table 2 on our scenes: gen:tree 30 degrees
# off axis and the molecule 2XHE 25 degrees off axis, at 1.75, 3.5, 7 and
# 14 radii, 124 x 124, eps 1 px; also build time and size against spheres.
# Usage: benches/cubes_table2.sh [DATA_DIR]   (default ../shared/data)
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-${FARFIELD_DATA:-../shared/data}}
out=$(mktemp -d)
cargo build --release -q -p farfield-server -p farfield-cli
server=target/release/farfield-server
client=target/release/farfield
for input in gen:tree "$data/2XHE.pdb" "$data/stanford-bunny.obj"; do
  name=$(basename "$input" | tr ':' '_')
  for kind in spheres cubes; do
    $server build "$input" --kind $kind --out "$out/$name.$kind.ff" --json |
      python3 -c "import json,sys; d=json.load(sys.stdin); print('$name $kind: build %.2f s, %d bytes, %d nodes, %.1f bytes/node' % (d['seconds'], d['file_bytes'], d['stats']['nodes'], d['bytes_per_node']))"
  done
done
$client bench-cubes --file "$out/gen_tree.cubes.ff" --input gen:tree --azimuth 30 --repeats 5
$client bench-cubes --file "$out/2XHE.pdb.cubes.ff" --input "$data/2XHE.pdb" --azimuth 25 --repeats 3
rm -rf "$out"
