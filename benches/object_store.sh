#!/usr/bin/env bash
# Scenes in object storage against the same scene on local disk, under the
# same load clients: time to first image and to refined, pages/s, and the
# requests and bytes the store served per client, for 1 and 16 clients,
# each with the server's page cache cold (a fresh server) and warm (the
# same load again); the store's side with and without coalescing the
# read-ahead of neighbouring pages, and with a local-disk second tier under
# a page cache too small for the scene (4 MiB), where the tier, not the
# store, serves what the cache lost. Then the same scene from 1, 2 and 3
# replicas behind nginx (docker/nginx/balancer.conf, round robin here so
# one scene's clients spread), all on this machine's cores.
#
# The store is s3s-fs on loopback (cargo install s3s-fs --version 0.14.1
# --features binary): no network latency, so the store's costs here are
# its requests' CPU and round trips on loopback, not a remote store's.
#
# Usage: benches/object_store.sh [OUT_DIR] (binaries from target/release;
#   CLIENTS ("1 16"), SECONDS_RUN (20), TREES (32), SIZE, FPS, REPLICA_CLIENTS
#   (48) override the defaults).
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(mkdir -p "${1:-runs/object-store}" && cd "${1:-runs/object-store}" && pwd)
seconds=${SECONDS_RUN:-20}; trees=${TREES:-32}
bin=$(pwd)/target/release
command -v s3s-fs >/dev/null || [ -x "$HOME/.cargo/bin/s3s-fs" ] ||
  { echo "s3s-fs not found (cargo install s3s-fs --version 0.14.1 --features binary)" >&2; exit 1; }
s3s=$(command -v s3s-fs || echo "$HOME/.cargo/bin/s3s-fs")
[ -x $bin/farfield ] && [ -x $bin/farfield-server ] ||
  cargo build --release -p farfield-cli -p farfield-server
mkdir -p "$out/scenes" "$out/store/scenes" "$out/nginx/tmp"
scene=$out/scenes/island.ff
[ -f "$scene" ] || $bin/farfield-server build gen:island --param trees=$trees --out "$scene"

pids=()
trap 'kill ${pids[@]} 2>/dev/null || true; wait 2>/dev/null || true' EXIT
RUST_LOG=info NO_COLOR=1 "$s3s" --host 127.0.0.1 --port 0 --access-key bench --secret-key bench-secret \
  "$out/store" > "$out/s3s.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do
  store_port=$(sed -n 's/.*server is running at http:\/\/127.0.0.1:\([0-9]*\).*/\1/p' "$out/s3s.log" | head -1)
  [ -n "$store_port" ] && break
  sleep 0.1
done
export AWS_ENDPOINT_URL=http://127.0.0.1:$store_port AWS_ACCESS_KEY_ID=bench \
  AWS_SECRET_ACCESS_KEY=bench-secret AWS_REGION=us-east-1
$bin/farfield-server publish "$scene" s3://scenes/island.ff

# Starts a server (extra arguments as given) and prints its address and
# pid. It never lists the store again (--rescan-seconds 0), so the store's
# requests counted are the pages' alone.
serve() {
  local log=$out/server-$RANDOM.log
  $bin/farfield-server serve --listen 127.0.0.1:0 --rescan-seconds 0 "$@" > "$log" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do
    addr=$(sed -n 's/^listening on //p' "$log" | head -1)
    [ -n "$addr" ] && { echo "$addr $!"; return; }
    sleep 0.1
  done
  echo "the server did not start: $(cat "$log")" >&2; exit 1
}
metric() { curl -s "http://$1/metrics" | awk -v n="$2" '$1 == n { print $2 }'; }

load() { # ADDR CLIENTS RUN
  $bin/farfield loadtest --server "http://$1" --scene island --clients "$2" --duration "$seconds" \
    --size "${SIZE:-800x600}" --fps "${FPS:-10}" --client-cache-mib 32 --out "$3" --json > "$3.json"
}

report() { # RUN.json SOURCE CACHE REQUESTS BYTES TIER_HITS
  python3 - "$@" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
f = lambda v: "-" if v is None else f"{v:.0f}"
n = r["clients"]
req, byt = float(sys.argv[4]), float(sys.argv[5])
print(f"{sys.argv[2]:<14} {sys.argv[3]:<5} {n:>7} {f(r['first_image_p50_ms']):>11} {f(r['refined_p50_ms']):>12} "
      f"{r['pages_per_s']:>8.0f} {req / n:>12.1f} {byt / n / 1e6:>12.2f} {float(sys.argv[6]) / n:>10.1f}  "
      f"{r['clients_refined']}/{n} refined, errors {r['errors']}")
PY
}

printf '%-14s %-5s %7s %11s %12s %8s %12s %12s %10s\n' source cache clients "first p50" "refined p50" \
  pages/s "requests/cl" "store MB/cl" "tier/cl"
for clients in ${CLIENTS:-1 16}; do
  for source in file store store-single store-tier; do
    case $source in
      file) read -r addr pid < <(serve --scenes "$out/scenes") ;;
      store) read -r addr pid < <(serve --scenes s3://scenes) ;;
      store-single) read -r addr pid < <(serve --scenes s3://scenes --store-coalesce-bytes 0) ;;
      store-tier) rm -rf "$out/tier"
        read -r addr pid < <(serve --scenes s3://scenes --store-tier-dir "$out/tier" --store-tier-bytes $((1 << 30)) --cache-bytes $((4 << 20))) ;;
    esac
    [ -n "${pid:-}" ] || exit 1
    pids+=("$pid")
    for cache in cold warm; do
      run=$out/$source-$clients-$cache
      r0=$(metric "$addr" farfield_store_requests_total); b0=$(metric "$addr" farfield_store_bytes_total)
      t0=$(metric "$addr" farfield_store_tier_hits_total)
      load "$addr" "$clients" "$run"
      r1=$(metric "$addr" farfield_store_requests_total); b1=$(metric "$addr" farfield_store_bytes_total)
      t1=$(metric "$addr" farfield_store_tier_hits_total)
      report "$run.json" "$source" "$cache" $((r1 - r0)) $((b1 - b0)) $((t1 - t0))
    done
    kill "$pid"; wait "$pid" 2>/dev/null || true
  done
done

# Replicas behind the balancer.
replica_clients=${REPLICA_CLIENTS:-48}
echo
printf '%-9s %7s %8s %9s %9s %11s %12s\n' replicas clients pages/s "lat p50" "lat p99" "first p50" "refined p50"
for n in 1 2 3; do
  upstream=""; started=()
  for _ in $(seq "$n"); do
    read -r addr pid < <(serve --scenes s3://scenes)
    [ -n "${pid:-}" ] || exit 1
    pids+=("$pid")
    upstream+="    server $addr max_fails=1 fail_timeout=5s;"$'\n'; started+=("$pid")
  done
  port=$((18180 + n))
  sed "s/listen 8080;/listen 127.0.0.1:$port;/" docker/nginx/balancer.conf > "$out/nginx/balancer.conf"
  cat > "$out/nginx/nginx.conf" <<CONF
worker_processes 1;
daemon off;
pid $out/nginx/nginx.pid;
error_log $out/nginx/error.log warn;
events { worker_connections 4096; }
http {
  access_log off;
  client_body_temp_path $out/nginx/tmp; proxy_temp_path $out/nginx/tmp;
  fastcgi_temp_path $out/nginx/tmp; uwsgi_temp_path $out/nginx/tmp; scgi_temp_path $out/nginx/tmp;
  upstream farfield {
$upstream  }
  include $out/nginx/balancer.conf;
}
CONF
  nginx -c "$out/nginx/nginx.conf" -p "$out/nginx" &
  nginx_pid=$!; pids+=($nginx_pid)
  for _ in $(seq 100); do curl -sf -o /dev/null "http://127.0.0.1:$port/healthz" && break; sleep 0.1; done
  run=$out/replicas-$n
  load "127.0.0.1:$port" "$replica_clients" "$run"
  python3 - "$run.json" "$n" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
f = lambda v: "-" if v is None else f"{v:.0f} ms"
print(f"{sys.argv[2]:<9} {r['clients']:>7} {r['pages_per_s']:>8.0f} {f(r['latency_p50_ms']):>9} "
      f"{f(r['latency_p99_ms']):>9} {f(r['first_image_p50_ms']):>11} {f(r['refined_p50_ms']):>12}  "
      f"{r['clients_refined']}/{r['clients']} refined, errors {r['errors']}")
PY
  kill "$nginx_pid" "${started[@]}"; wait "$nginx_pid" "${started[@]}" 2>/dev/null || true
done
