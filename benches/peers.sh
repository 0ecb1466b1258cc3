#!/usr/bin/env bash
# farfield against PotreeConverter 2, side by side in one run: generated
# lidar (`farfield-server lidar-tiles`: a terrain with RGB, in 4 LAS tiles
# with their own offsets) of each size, built by both tools alternately,
# ROUNDS times each; wall time and peak resident memory from
# /usr/bin/time, output bytes and bytes a point. Inputs are deleted after
# each size.
#
# Usage: benches/peers.sh [MILLIONS...]   (default: 10 50 100)
#   POTREE      the PotreeConverter binary, or
#   POTREE_SRC  its source (develop branch), built here with cmake into
#               POTREE_SRC/build when POTREE is not set (needs cmake,
#               libtbb-dev and a C++ compiler)
#   POTREE_METHODS  its sampling methods to run (default: "poisson random";
#               poisson is its default)
#   FARFIELD_BIN_DIR  farfield's binaries (default: target/release)
#   FARFIELD_MEMORY  farfield's memory budgets (`build --memory`) to run,
#               "default" for none given (default: "default 512M": in
#               memory, and out of core in chunks spilled under WORK)
#   ROUNDS      runs of each tool a size (default 2)
#   WORK        where inputs and outputs go (default: a new folder in /tmp)
set -euo pipefail
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(10 50 100)
bin=${FARFIELD_BIN_DIR:-target/release}
rounds=${ROUNDS:-2}
methods=${POTREE_METHODS:-poisson random}
budgets=${FARFIELD_MEMORY:-default 512M}
work=${WORK:-$(mktemp -d /tmp/farfield-peers.XXXXXX)}
mkdir -p "$work"

potree=${POTREE:-}
if [ -z "$potree" ]; then
  src=${POTREE_SRC:?set POTREE (a PotreeConverter binary) or POTREE_SRC (its source)}
  if [ ! -x "$src/build/PotreeConverter" ]; then
    mkdir -p "$src/build"
    (cd "$src/build" && cmake -DCMAKE_BUILD_TYPE=Release .. >/dev/null && make -j"$(nproc)" >/dev/null)
  fi
  potree=$src/build/PotreeConverter
fi
for tool in /usr/bin/time bc; do
  command -v $tool >/dev/null 2>&1 || { echo "needs $tool (apt-get install time bc)" >&2; exit 1; }
done
[ -x "$bin/farfield-server" ] || { echo "no $bin/farfield-server: cargo build --release -p farfield-server" >&2; exit 1; }

# Runs a command; prints "wall_seconds peak_MiB".
measure() {
  local stats=$work/time.txt
  /usr/bin/time -f "%e %M" -o "$stats" "$@" >"$work/run.log" 2>&1 ||
    { echo "failed: $*" >&2; tail -5 "$work/run.log" >&2; exit 1; }
  awk '{ printf "%.1f %.0f\n", $1, $2 / 1024 }' "$stats"
}

printf '%-9s %-22s %5s %9s %9s %14s %10s\n' points tool round wall_s peak_MiB bytes bytes/point
for m in "${sizes[@]}"; do
  points=$((m * 1000000))
  "$bin/farfield-server" lidar-tiles --points $points --grid 2 --out "$work/in" >/dev/null
  for round in $(seq 1 "$rounds"); do
    for budget in $budgets; do
      rm -f "$work/out.ff"
      memory=()
      name=farfield
      if [ "$budget" != default ]; then
        memory=(--memory "$budget" --tmp "$work")
        name="farfield-$budget"
      fi
      read -r wall peak < <(measure "$bin/farfield-server" build "$work"/in/*.las --out "$work/out.ff" "${memory[@]}")
      bytes=$(stat -c %s "$work/out.ff")
      printf '%-9s %-22s %5s %9s %9s %14s %10.2f\n' $points "$name" "$round" "$wall" "$peak" "$bytes" \
        "$(echo "$bytes / $points" | bc -l)"
    done
    for method in $methods; do
      rm -rf "$work/potree"
      read -r wall peak < <(measure "$potree" "$work/in" -o "$work/potree" -m "$method")
      bytes=$(du -sb "$work/potree" | cut -f1)
      printf '%-9s %-22s %5s %9s %9s %14s %10.2f\n' $points "PotreeConverter-$method" "$round" "$wall" "$peak" \
        "$bytes" "$(echo "$bytes / $points" | bc -l)"
    done
  done
  rm -rf "$work/in" "$work/out.ff" "$work/potree"
done
