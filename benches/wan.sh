#!/usr/bin/env bash
# Streaming over an emulated wide-area network against loopback: the server
# in one network namespace, load clients in another, joined by `farfield
# wan` (default 40 ms round trip, 100 Mbit/s, 0.1 % loss; needs root,
# /dev/net/tun and iproute2). For 1 and 16 clients, with and without server
# push, prints time to first image, time to refined, pages and bytes, and
# the request latency. The test `wan` is this scaled down for CI.
#
# Usage: benches/wan.sh [OUT_DIR] (binaries from target/release;
#   RTT_MS, RATE_MBIT, LOSS_PERCENT, TREES, CLIENTS ("1 16"), SECONDS_RUN override).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-runs/wan}
seconds=${SECONDS_RUN:-20}; trees=${TREES:-32}
bin=$(pwd)/target/release
[ -x $bin/farfield ] && [ -x $bin/farfield-server ] ||
  cargo build --release -p farfield-cli -p farfield-server
mkdir -p "$out/scenes"
scene=$out/scenes/island.ff
[ -f "$scene" ] || $bin/farfield-server build gen:island --param trees=$trees --out "$scene"

name=ffb$$
$bin/farfield wan --name $name --rtt-ms "${RTT_MS:-40}" --rate-mbit "${RATE_MBIT:-100}" \
  --loss-percent "${LOSS_PERCENT:-0.1}" > "$out/wan.log" 2>&1 &
wan=$!
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  # The link removes its namespaces when told to stop.
  kill -TERM $wan 2>/dev/null || true
  wait 2>/dev/null || true
}
trap cleanup EXIT
for _ in $(seq 100); do
  grep -q '^ready' "$out/wan.log" && break
  sleep 0.1
done
grep '^ready' "$out/wan.log" || { echo "the link did not start: $(cat "$out/wan.log")" >&2; exit 1; }

# serve NETNS ADDRESS LOG: a server, its address printed.
serve() {
  local prefix=()
  [ "$1" = - ] || prefix=(ip netns exec "$1")
  "${prefix[@]}" $bin/farfield-server serve --scenes "$out/scenes" --listen "$2:0" > "$3" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do
    addr=$(sed -n 's/^listening on //p' "$3" | head -1)
    [ -n "$addr" ] && { echo "$addr"; return; }
    sleep 0.1
  done
  echo "the server did not start: $(cat "$3")" >&2; exit 1
}
local_addr=$(serve - 127.0.0.1 "$out/server-loopback.log")
wan_addr=$(serve "$name-server" 10.201.0.1 "$out/server-wan.log")

printf '%-9s %-5s %7s %12s %12s %12s %10s %8s %8s %8s %9s\n' network push clients \
  "first p50" "refined p50" "refined max" "pages/s" "MB/s" "MB" "lat p50" "lat p99"
for clients in ${CLIENTS:-1 16}; do
  for push in off on; do
    for network in loopback wan; do
      run=$out/$network-$clients-$push
      args=(--scene island --clients "$clients" --duration "$seconds" --size 800x600 --out "$run" --json)
      [ $push = on ] && args+=(--push)
      if [ $network = wan ]; then
        ip netns exec "$name-client" $bin/farfield loadtest --server "http://$wan_addr" "${args[@]}" > "$run.json"
      else
        $bin/farfield loadtest --server "http://$local_addr" "${args[@]}" > "$run.json"
      fi
      python3 - "$run.json" "$network" "$push" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
f = lambda v: "-" if v is None else f"{v:.0f} ms"
print(f"{sys.argv[2]:<9} {sys.argv[3]:<5} {r['clients']:>7} {f(r['first_image_p50_ms']):>12} "
      f"{f(r['refined_p50_ms']):>12} {f(r['refined_max_ms']):>12} {r['pages_per_s']:>10.0f} "
      f"{r['mb_per_s']:>8.2f} {r['bytes'] / 1e6:>8.1f} {f(r['latency_p50_ms']):>8} {f(r['latency_p99_ms']):>9}  refined {r['clients_refined']}/{r['clients']}, errors {r['errors']}")
PY
    done
  done
done
