#!/usr/bin/env bash
# A build far larger than memory inside a 4 GiB memory cgroup (v1, as
# root), with the default --memory (half the cgroup's limit), against a
# 10 M build in the same cgroup: generated lidar (`lidar-tiles --grid 4`,
# 26 bytes a point: 1 billion points need about 26 GB of inputs and
# about 36 GB of temporary files at once beside them). Prints each
# build's wall time and peak resident memory, the cgroup's peak and OOM
# kills, and the build's phases. Inputs are deleted after each build; the
# scene stays in WORK (for benches/big_load.sh).
#
# Usage: BIG=500 benches/big_build.sh   (millions of points; default 500)
#   FARFIELD_BIN_DIR (default target/release), WORK (default /tmp/farfield-big)
#   MESH=1: millions of triangles of a generated mesh instead (`gen:forest`,
#   20 trees of 50,000 triangles a million, every instance placed; no
#   input file), 10 against BIG (default 100).
set -euo pipefail
bin=${FARFIELD_BIN_DIR:-target/release}
w=${WORK:-/tmp/farfield-big}; rm -rf $w; mkdir -p $w
[ "$(id -u)" -eq 0 ] && [ -d /sys/fs/cgroup/memory ] || { echo "needs root and cgroup v1's memory controller" >&2; exit 1; }
cg=/sys/fs/cgroup/memory/farfield-big
[ -d $cg ] || mkdir $cg
echo $((4 << 30)) > $cg/memory.limit_in_bytes
incg() { ( echo $BASHPID > $cg/cgroup.procs; exec "$@" ); }
mesh=${MESH:-}
for m in 10 ${BIG:-$([ -n "$mesh" ] && echo 100 || echo 500)}; do
  if [ -n "$mesh" ]; then
    input=(gen:forest --param trees=$((m * 20)))
  else
    s=$(date +%s.%N)
    $bin/farfield-server lidar-tiles --points $((m * 1000000)) --grid 4 --out $w/in-$m >/dev/null
    echo "$m M: generated $(du -sb $w/in-$m | cut -f1) bytes in $(echo "$(date +%s.%N) - $s" | bc) s"
    input=($w/in-$m)
  fi
  echo 0 > $cg/memory.max_usage_in_bytes
  incg /usr/bin/time -f "%e s wall, %M KiB peak RSS" -o $w/time-$m $bin/farfield-server build "${input[@]}" --out $w/out-$m.ff --tmp $w --json > $w/build-$m.json 2> $w/build-$m.err ||
    { echo "build $m failed"; tail -5 $w/build-$m.err; cat $w/time-$m; grep -E "oom_kill|under_oom" $cg/memory.oom_control; exit 1; }
  echo "$m M: $(cat $w/time-$m); cgroup max usage $(( $(cat $cg/memory.max_usage_in_bytes) >> 20 )) MiB; $(grep "^oom_kill " $cg/memory.oom_control)"
  jq -c '{input_vertices, file_bytes, bytes_per_input, seconds, memory_budget, out_of_core, chunks: .stats.chunks, s_count: .stats.seconds_count, s_spread: .stats.seconds_spread, s_chunks: .stats.seconds_chunks, s_top: .stats.seconds_top, s_levels: .stats.seconds_levels, s_pages: .stats.seconds_pages}' $w/build-$m.json
  rm -rf $w/in-$m
done
