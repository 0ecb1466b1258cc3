#!/usr/bin/env bash
# Time to first image over an emulated wide-area network against the
# scene's size: `benches/first_image.sh` measures bytes and loopback time;
# this puts the server and one client in network namespaces joined by
# `farfield wan` (default 40 ms round trip, 100 Mbit/s, no loss; needs
# root, /dev/net/tun and iproute2), where bytes before the first image
# become time. For each size, generated lidar (`lidar-tiles`, 4 tiles) is
# built (`--memory 512M`) by the new binaries and, with OLD_BIN_DIR, by an
# earlier commit's; then ROUNDS times each, alternately, one load client
# (`farfield loadtest --clients 1`) connects and draws its first image.
#
# Usage: benches/first_image_wan.sh [MILLIONS...]   (default: 10 100)
#   FARFIELD_BIN_DIR, OLD_BIN_DIR, WORK: as in benches/first_image.sh
#   ROUNDS (default 5), RTT_MS (40), RATE_MBIT (100)
set -euo pipefail
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(10 100)
new=${FARFIELD_BIN_DIR:-target/release}
old=${OLD_BIN_DIR:-}
rounds=${ROUNDS:-5}
work=${WORK:-$(mktemp -d /tmp/farfield-first-image-wan.XXXXXX)}
mkdir -p "$work/scenes-new" "$work/scenes-old"
command -v jq >/dev/null 2>&1 || { echo "needs jq (apt-get install jq)" >&2; exit 1; }
[ "$(id -u)" -eq 0 ] || { echo "needs root (network namespaces)" >&2; exit 1; }

name=ffi$(($$ % 100000))
"$new/farfield" wan --name $name --rtt-ms "${RTT_MS:-40}" --rate-mbit "${RATE_MBIT:-100}" \
  --loss-percent 0 > "$work/wan.log" 2>&1 &
wan=$!
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  kill -TERM $wan 2>/dev/null || true
  wait 2>/dev/null || true
}
trap cleanup EXIT
for _ in $(seq 100); do
  grep -q '^ready' "$work/wan.log" && break
  sleep 0.1
done
grep -q '^ready' "$work/wan.log" || { echo "the link did not start: $(cat "$work/wan.log")" >&2; exit 1; }

# A server of the binaries in $1 over $2 in the server's namespace; its address.
serve() {
  local log=$work/serve-$(basename "$2").log
  ip netns exec "$name-server" "$1/farfield-server" serve --scenes "$2" --listen 10.201.0.1:0 > "$log" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do
    addr=$(sed -n 's/^listening on //p' "$log" | head -1)
    [ -n "$addr" ] && { echo "$addr"; return; }
    sleep 0.1
  done
  echo "the server did not start: $(cat "$log")" >&2; exit 1
}

bins=(new)
[ -n "$old" ] && bins+=(old)
printf '%-10s %-4s %8s %12s %s\n' points bin pages header_B "first image ms (one client each)"
for m in "${sizes[@]}"; do
  points=$((m * 1000000))
  scene=lidar$m
  "$new/farfield-server" lidar-tiles --points $points --grid 2 --out "$work/in" >/dev/null
  for which in "${bins[@]}"; do
    dir=$new
    [ "$which" = old ] && dir=$old
    "$dir/farfield-server" build "$work"/in/*.las --out "$work/scenes-$which/$scene.ff" \
      --memory 512M --tmp "$work" > "$work/build.log" 2>&1 ||
      { echo "build failed ($dir):" >&2; tail -5 "$work/build.log" >&2; exit 1; }
  done
  rm -rf "$work/in"
  declare -A addr times
  for which in "${bins[@]}"; do
    dir=$new
    [ "$which" = old ] && dir=$old
    addr[$which]=$(serve "$dir" "$work/scenes-$which")
    times[$which]=""
  done
  for _ in $(seq 1 "$rounds"); do
    for which in "${bins[@]}"; do
      dir=$new
      [ "$which" = old ] && dir=$old
      ms=$(ip netns exec "$name-client" "$dir/farfield" loadtest --server "http://${addr[$which]}" \
        --scene $scene --clients 1 --duration 2 --size 400x300 --out "$work/load" --json |
        jq -r '.first_image_p50_ms')
      times[$which]+=" $(printf '%.0f' "$ms")"
    done
  done
  for which in "${bins[@]}"; do
    dir=$new
    [ "$which" = old ] && dir=$old
    info=$("$dir/farfield-server" inspect "$work/scenes-$which/$scene.ff" --json)
    printf '%-10s %-4s %8s %12s %s\n' $points "$which" "$(jq -r .pages <<<"$info")" \
      "$(jq -r .header_bytes <<<"$info")" "${times[$which]}"
  done
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  pids=()
  rm -f "$work"/scenes-*/"$scene.ff"
done
