#!/usr/bin/env bash
# Out of core at full size: a generated island whose file is more than four
# times the server's page cache and larger than all the memory the server
# process may hold (a memory cgroup made here, cgroup v1 or v2; needs root),
# served to 64 load clients for 60 s on loopback. Prints the load test's
# summary (0 errors is the target; p99 request latency; pages/s, MB/s;
# server resident memory over time) and the cgroup's peak and OOM kills.
# The test `out_of_core` is this scaled down for CI.
#
# Usage: benches/out_of_core.sh [OUT_DIR] (binaries from target/release;
#   CLIENTS, SECONDS_RUN, CACHE_MIB, LIMIT_MIB, TREES, SIZE, FPS override the defaults;
#   LOADTEST_ARGS adds flags to the load test, e.g. "--max-outstanding 8").
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/out-of-core}
clients=${CLIENTS:-64}; seconds=${SECONDS_RUN:-60}
cache_mib=${CACHE_MIB:-64}; limit_mib=${LIMIT_MIB:-192}; trees=${TREES:-1000}
bin=target/release
[ -x $bin/farfield ] && [ -x $bin/farfield-server ] ||
  cargo build --release -p farfield-cli -p farfield-server
mkdir -p "$out/scenes"
scene=$out/scenes/island.ff
[ -f "$scene" ] || $bin/farfield-server build gen:island --param trees=$trees --out "$scene"
bytes=$(stat -c %s "$scene")
cache=$((cache_mib << 20)); limit=$((limit_mib << 20))
if [ "$bytes" -lt $((4 * cache)) ] || [ "$bytes" -le "$limit" ]; then
  echo "the scene ($bytes bytes) must be at least 4x the cache and over the limit: raise TREES" >&2
  exit 1
fi

# The cgroup: v1's memory controller, else v2.
leaf=farfield-bench-$$
if [ -e /sys/fs/cgroup/memory/memory.limit_in_bytes ]; then
  own=$(awk -F: '$2 ~ /(^|,)memory(,|$)/ { print $3 }' /proc/self/cgroup)
  cg=/sys/fs/cgroup/memory$own/$leaf
  mkdir "$cg"
  echo $limit > "$cg/memory.limit_in_bytes"
  [ -e "$cg/memory.memsw.limit_in_bytes" ] && echo $limit > "$cg/memory.memsw.limit_in_bytes"
  peak_file=memory.max_usage_in_bytes; oom_file=memory.oom_control
else
  own=$(awk -F: '$1 == "0" { print $3 }' /proc/self/cgroup)
  echo +memory > "/sys/fs/cgroup$own/cgroup.subtree_control" 2>/dev/null || true
  cg=/sys/fs/cgroup$own/$leaf
  mkdir "$cg"
  echo $limit > "$cg/memory.max"
  [ -e "$cg/memory.swap.max" ] && echo 0 > "$cg/memory.swap.max"
  peak_file=memory.peak; oom_file=memory.events
fi
server_log=$out/server.log
# The shell joins the cgroup, then becomes the server: all of its memory counts.
sh -c "echo \$\$ > '$cg/cgroup.procs' && exec $bin/farfield-server serve --scenes '$out/scenes' \
  --listen 127.0.0.1:0 --cache-bytes $cache" > "$server_log" 2>&1 &
server=$!
cleanup() {
  kill $server 2>/dev/null || true
  wait $server 2>/dev/null || true
  rmdir "$cg" 2>/dev/null || true
}
trap cleanup EXIT
for _ in $(seq 100); do
  addr=$(sed -n 's/^listening on //p' "$server_log" | head -1)
  [ -n "$addr" ] && break
  sleep 0.1
done
[ -n "$addr" ] || { echo "the server did not start: $(cat "$server_log")" >&2; exit 1; }
echo "scene $bytes bytes, server page cache $cache bytes, memory limit $limit bytes, $clients clients for $seconds s"
$bin/farfield loadtest --server "http://$addr" --scene island --clients "$clients" \
  --duration "$seconds" --ramp 5 --size "${SIZE:-800x600}" --fps "${FPS:-10}" --client-cache-mib 32 ${LOADTEST_ARGS:-} --out "$out/load"
echo "cgroup: peak $(cat "$cg/$peak_file" 2>/dev/null || echo -) bytes; $(grep oom_kill "$cg/$oom_file" || echo 'oom_kill -')"
kill -0 $server 2>/dev/null || { echo "the server died" >&2; exit 1; }
