#!/usr/bin/env bash
# Issue 2's measurements in one run: build throughput and peak memory,
# bytes per node of every shared data file, and traversal rate.
# Usage: benches/sphere_hierarchy.sh [DATA_DIR]   (default ../shared/data)
set -euo pipefail
cd "$(dirname "$0")/.."
data=${1:-${FARFIELD_DATA:-../shared/data}}
out=$(mktemp -d)
cargo build --release -q -p farfield-server
bin=target/release/farfield-server

echo "== build throughput (median of repeats, import + build, nothing written)"
$bin bench build "$data/horse.ply" --repeats 7
$bin bench build "$data/igea.ply" --repeats 7
$bin bench build gen:island --param size=2048 --param trees=256 --repeats 3
# A lidar point cloud: sized by nearest neighbours, not triangles.
$bin bench build "$data/autzen_trim.las" --repeats 9

echo "== file size (bytes per node, page headers and checksums included)"
for f in "$data"/*.obj "$data"/*.ply "$data"/*.las "$data"/*.pdb gen:island gen:tree; do
  name=$(basename "$f")
  $bin build "$f" --out "$out/$name.ff" >/dev/null
  $bin inspect "$out/$name.ff"
done

echo "== traversal rate (one core, whole model at 1 px)"
$bin bench traverse "$out/gen:island.ff" --repeats 15
$bin bench traverse "$out/igea.ply.ff" --repeats 15
$bin bench traverse "$out/horse.ply.ff" --repeats 15
rm -rf "$out"
