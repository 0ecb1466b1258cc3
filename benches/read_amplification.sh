#!/usr/bin/env bash
# Read amplification under a small page cache: the generated island of
# about 298 MB (18,138 pages) served with a page cache of 32 MiB, 64 MiB
# and the default (256 MiB) to 16 and 64 load clients for 30 s each, and
# for each run the server's disk reads per page served and the clients'
# request latency quantiles. Two builds side by side, alternating run by
# run, so both see the same machine: BEFORE and AFTER are folders holding
# `farfield` and `farfield-server` (default: AFTER=target/release, and no
# BEFORE).
#
# Usage: [BEFORE=dir] [AFTER=dir] benches/read_amplification.sh [OUT_DIR]
#   CACHES (MiB, "default" for the server's own), CLIENT_COUNTS, SECONDS_RUN,
#   TREES override the defaults.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/read-amplification}
after=${AFTER:-target/release}
caches=${CACHES:-"32 64 default"}
client_counts=${CLIENT_COUNTS:-"16 64"}
seconds=${SECONDS_RUN:-30}
trees=${TREES:-1000}
builds=()
[ -n "${BEFORE:-}" ] && builds+=("before=$BEFORE")
builds+=("after=$after")
for b in "${builds[@]}"; do
  dir=${b#*=}
  [ -x "$dir/farfield" ] && [ -x "$dir/farfield-server" ] || { echo "no binaries in $dir" >&2; exit 1; }
done
mkdir -p "$out/scenes"
scene=$out/scenes/island.ff
[ -f "$scene" ] || "$after/farfield-server" build gen:island --param trees=$trees --out "$scene"
echo "scene: $(stat -c %s "$scene") bytes"

run() { # name bin cache clients
  local name=$1 bin=$2 cache=$3 clients=$4
  local dir=$out/$name-cache$cache-clients$clients
  mkdir -p "$dir"
  local cache_args=()
  [ "$cache" = default ] || cache_args=(--cache-bytes $((cache << 20)))
  "$bin/farfield-server" serve --scenes "$out/scenes" --listen 127.0.0.1:0 "${cache_args[@]}" \
    > "$dir/server.log" 2>&1 &
  local server=$! addr=""
  for _ in $(seq 100); do
    addr=$(sed -n 's/^listening on //p' "$dir/server.log" | head -1)
    [ -n "$addr" ] && break
    sleep 0.1
  done
  [ -n "$addr" ] || { echo "the server did not start: $(cat "$dir/server.log")" >&2; exit 1; }
  "$bin/farfield" loadtest --server "http://$addr" --scene island --clients "$clients" \
    --duration "$seconds" --out "$dir/load" > "$dir/loadtest.log" 2>&1 || true
  kill $server; wait $server 2>/dev/null || true
  python3 - "$dir/load/loadtest.json" "$name" "$cache" "$clients" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
f = lambda k, d=2: "-" if s.get(k) is None else f"{s[k]:.{d}f}"
print(f"| {sys.argv[2]} | {sys.argv[3]} | {sys.argv[4]} | {f('server_disk_reads_per_page_served')} | "
      f"{f('latency_p50_ms', 1)} / {f('latency_p95_ms', 1)} / {f('latency_p99_ms', 1)} | "
      f"{f('pages_per_s', 0)} | {f('server_cache_hit_rate', 3)} | {s.get('errors', '-')} |")
PY
}

echo "| build | cache MiB | clients | disk reads a page served | latency p50 / p95 / p99 (ms) | pages/s | cache hit rate | errors |"
echo "|---|---|---|---|---|---|---|---|"
for cache in $caches; do
  for clients in $client_counts; do
    for b in "${builds[@]}"; do
      run "${b%%=*}" "${b#*=}" "$cache" "$clients"
    done
  done
done
