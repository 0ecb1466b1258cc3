#!/usr/bin/env bash
# 16 load clients for 60 s (400x300, 2 traversals a second, started over
# 5 s) on the scene benches/big_build.sh made and on the island of
# benches/out_of_core.sh (`gen:island trees=1000`), alternately, twice,
# one server on loopback with its default page cache. Prints each run's
# errors, pages/s, request latency and first image, and the server's peak
# resident memory.
#
# Usage: BIG=500 benches/big_load.sh   (FARFIELD_BIN_DIR, WORK as in big_build.sh)
set -euo pipefail
bin=${FARFIELD_BIN_DIR:-target/release}
big=${WORK:-/tmp/farfield-big}
w=$big/load; mkdir -p $w/scenes
[ -f $w/scenes/island.ff ] || $bin/farfield-server build gen:island --param trees=1000 --out $w/scenes/island.ff > /dev/null
ln -sf $big/out-${BIG:-500}.ff $w/scenes/lidar.ff
$bin/farfield-server serve --scenes $w/scenes --listen 127.0.0.1:0 > $w/server.log 2>&1 &
server=$!; trap "kill $server" EXIT
for _ in $(seq 100); do addr=$(sed -n 's/^listening on //p' $w/server.log | head -1); [ -n "$addr" ] && break; sleep 0.1; done
for round in 1 2; do
for scene in island lidar; do
  $bin/farfield loadtest --server "http://$addr" --scene $scene --clients 16 --duration ${SECONDS_RUN:-60} --ramp 5 \
    --size 400x300 --fps 2 --client-cache-mib 32 --out $w/$scene-$round --json > $w/$scene-$round.json
  jq -c --arg s $scene '{scene: $s, errors, clients, clients_with_first_image, clients_refined, pages_per_s, mb_per_s, latency_p50_ms, latency_p99_ms, latency_max_ms, first_image_p50_ms}' $w/$scene-$round.json
done
done
echo "server peak RSS: $(grep VmHWM /proc/$server/status)"
