#!/usr/bin/env bash
# The memory server against a static file server under the same load: the
# scene exported as plain files (`farfield-server export`) behind nginx,
# and the same load clients (`farfield loadtest --static`: GETs on 4
# keep-alive connections a client, as a browser viewer of Potree or 3D
# Tiles does) against the memory server's websocket. Prints both rows
# (with the CPU seconds each server used) and the ratios. Both servers,
# and the clients, share this machine's cores.
#
# Usage: benches/static_files.sh [OUT_DIR] (binaries from target/release;
#   nginx from Debian's nginx package; CLIENTS ("16 64"), SECONDS_RUN,
#   TREES, SIZE, FPS, PORT override the defaults).
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(mkdir -p "${1:-runs/static-files}" && cd "${1:-runs/static-files}" && pwd)
seconds=${SECONDS_RUN:-30}; trees=${TREES:-32}; port=${PORT:-18080}
bin=$(pwd)/target/release
command -v nginx >/dev/null || { echo "nginx not found (apt-get install nginx)" >&2; exit 1; }
[ -x $bin/farfield ] && [ -x $bin/farfield-server ] ||
  cargo build --release -p farfield-cli -p farfield-server
mkdir -p "$out/scenes" "$out/nginx"
scene=$out/scenes/island.ff
[ -f "$scene" ] || $bin/farfield-server build gen:island --param trees=$trees --out "$scene"
[ -f "$out/static/island/header" ] || $bin/farfield-server export "$scene" --out "$out/static"

cat > "$out/nginx/nginx.conf" <<CONF
worker_processes 2;
daemon off;
pid $out/nginx/nginx.pid;
error_log $out/nginx/error.log;
events { worker_connections 8192; }
http {
  access_log off;
  sendfile on;
  tcp_nodelay on;
  keepalive_requests 1000000;
  keepalive_timeout 75s;
  default_type application/octet-stream;
  client_body_temp_path $out/nginx;
  proxy_temp_path $out/nginx;
  fastcgi_temp_path $out/nginx;
  uwsgi_temp_path $out/nginx;
  scgi_temp_path $out/nginx;
  server {
    listen 127.0.0.1:$port;
    root $out/static;
  }
}
CONF
nginx -c "$out/nginx/nginx.conf" -e "$out/nginx/error.log" &
nginx_pid=$!
$bin/farfield-server serve --scenes "$out/scenes" --listen 127.0.0.1:0 > "$out/server.log" 2>&1 &
server_pid=$!
trap 'kill $nginx_pid $server_pid 2>/dev/null || true; wait 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  addr=$(sed -n 's/^listening on //p' "$out/server.log" | head -1)
  [ -n "$addr" ] && curl -sf -o /dev/null "http://127.0.0.1:$port/island/header" && break
  sleep 0.1
done
[ -n "$addr" ] || { echo "the server did not start: $(cat "$out/server.log")" >&2; exit 1; }

# CPU seconds (user + system) of a process and its children so far.
cpu_s() {
  local total=0 pid
  for pid in "$@" $(pgrep -P "$1" || true); do
    total=$((total + $(awk '{ print $14 + $15 }' /proc/$pid/stat 2>/dev/null || echo 0)))
  done
  awk -v t="$total" -v hz="$(getconf CLK_TCK)" 'BEGIN { printf "%.1f", t / hz }'
}

printf '%-9s %7s %9s %7s %9s %9s %11s %12s %9s %s\n' server clients pages/s MB/s \
  "lat p50" "lat p99" "first p50" "refined p50" "CPU s" refined
for clients in ${CLIENTS:-16 64}; do
  for server in farfield nginx; do
    run=$out/$server-$clients
    args=(--scene island --clients "$clients" --duration "$seconds" --ramp 2
      --size "${SIZE:-800x600}" --fps "${FPS:-10}" --client-cache-mib 32 --out "$run" --json)
    pid=$server_pid; [ $server = nginx ] && pid=$nginx_pid
    before=$(cpu_s $pid)
    if [ $server = nginx ]; then
      $bin/farfield loadtest --server "http://127.0.0.1:$port" --static "${args[@]}" > "$run.json"
    else
      $bin/farfield loadtest --server "http://$addr" "${args[@]}" > "$run.json"
    fi
    cpu=$(awk -v a="$(cpu_s $pid)" -v b="$before" 'BEGIN { printf "%.1f", a - b }')
    python3 - "$run.json" "$server" "$cpu" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
f = lambda v: "-" if v is None else f"{v:.0f} ms"
print(f"{sys.argv[2]:<9} {r['clients']:>7} {r['pages_per_s']:>9.0f} {r['mb_per_s']:>7.2f} "
      f"{f(r['latency_p50_ms']):>9} {f(r['latency_p99_ms']):>9} {f(r['first_image_p50_ms']):>11} "
      f"{f(r['refined_p50_ms']):>12} {sys.argv[3]:>9} {r['clients_refined']}/{r['clients']}, errors {r['errors']}")
PY
  done
  python3 - "$out/farfield-$clients.json" "$out/nginx-$clients.json" <<'PY'
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
ratio = lambda x, y: "-" if not x or not y else f"{x / y:.2f}"
print(f"  farfield / nginx: pages/s {ratio(a['pages_per_s'], b['pages_per_s'])}, "
      f"latency p50 {ratio(a['latency_p50_ms'], b['latency_p50_ms'])}, "
      f"p99 {ratio(a['latency_p99_ms'], b['latency_p99_ms'])}, "
      f"first image {ratio(a['first_image_p50_ms'], b['first_image_p50_ms'])}")
PY
done
