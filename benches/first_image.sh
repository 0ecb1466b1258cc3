#!/usr/bin/env bash
# Time to first image and bytes before it, against the scene's size
# (issue 39: flat, whatever the size). For each size, generated lidar
# (`farfield-server lidar-tiles`, 4 LAS tiles with RGB) is built once
# (out of core, `--memory 512M`), then `farfield bench-stream` serves it
# on loopback and opens a client REPEATS times: connect, header, the
# pages the first image needs, one frame drawn. With OLD_BIN_DIR (the
# binaries of an earlier commit) each size is also built and measured by
# those, alternately with the new ones, in the same run. Inputs and
# outputs are deleted after each size.
#
# Usage: benches/first_image.sh [MILLIONS...]   (default: 1 10 100)
#   FARFIELD_BIN_DIR  farfield's binaries (default: target/release)
#   OLD_BIN_DIR       an earlier commit's binaries to compare (optional)
#   REPEATS           first images per run (default 9)
#   ROUNDS            runs of each binary a size (default 2)
#   WORK              where inputs and outputs go (default: a new folder in /tmp)
set -euo pipefail
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(1 10 100)
new=${FARFIELD_BIN_DIR:-target/release}
old=${OLD_BIN_DIR:-}
repeats=${REPEATS:-9}
rounds=${ROUNDS:-2}
work=${WORK:-$(mktemp -d /tmp/farfield-first-image.XXXXXX)}
mkdir -p "$work"
command -v jq >/dev/null 2>&1 || { echo "needs jq (apt-get install jq)" >&2; exit 1; }
for b in "$new" ${old:+"$old"}; do
  for exe in farfield farfield-server; do
    [ -x "$b/$exe" ] || { echo "no $b/$exe: cargo build --release -p farfield-cli -p farfield-server" >&2; exit 1; }
  done
done

# One build of the inputs by the binaries in $1 into $2.
build() {
  "$1/farfield-server" build "$work"/in/*.las --out "$2" --memory 512M --tmp "$work" >"$work/build.log" 2>&1 ||
    { echo "build failed ($1):" >&2; tail -5 "$work/build.log" >&2; exit 1; }
}

# The bytes a client needs before its first image, from `inspect --json`
# (files of format 3 on: the fixed header, the root directory page, page
# 0). A file of format 2 (before the paged directory) does not say: its
# header holds every page's entry, and page 0's length is the first
# entry's (a u32 at byte 144, after the 136 fixed bytes and the offset).
needed() {
  local info
  info=$("$1/farfield-server" inspect "$2" --json)
  if [ "$(jq -r '.format_version' <<<"$info")" = 2 ]; then
    echo $(($(jq -r '.header_bytes' <<<"$info") + $(od -An -tu4 -j144 -N4 "$2")))
  else
    jq -r '.first_image_bytes // "-"' <<<"$info"
  fi
}

printf '%-10s %-4s %5s %7s %9s %9s %11s %11s %9s %9s\n' \
  points bin round pages dir_pages header_B needed_B received_B ttfi_p50 ttfi_max
for m in "${sizes[@]}"; do
  points=$((m * 1000000))
  "$new/farfield-server" lidar-tiles --points $points --grid 2 --out "$work/in" >/dev/null
  bins=(new)
  build "$new" "$work/new.ff"
  if [ -n "$old" ]; then
    bins+=(old)
    build "$old" "$work/old.ff"
  fi
  rm -rf "$work/in"
  for round in $(seq 1 "$rounds"); do
    for which in "${bins[@]}"; do
      dir=$new
      [ "$which" = old ] && dir=$old
      file="$work/$which.ff"
      info=$("$dir/farfield-server" inspect "$file" --json)
      report=$("$dir/farfield" bench-stream "$file" --clients 1 --seconds 1 --repeats "$repeats" --json)
      printf '%-10s %-4s %5s %7s %9s %9s %11s %11s %9.1f %9.1f\n' $points "$which" "$round" \
        "$(jq -r '.pages' <<<"$info")" \
        "$(jq -r '.directory_pages // 0' <<<"$info")" \
        "$(jq -r '.header_bytes // "-"' <<<"$info")" \
        "$(needed "$dir" "$file")" \
        "$(jq -r '.bytes_to_first_image // "-"' <<<"$report")" \
        "$(jq -r '.time_to_first_image_median_ms' <<<"$report")" \
        "$(jq -r '.time_to_first_image_ms | max' <<<"$report")"
    done
  done
  rm -f "$work/new.ff" "$work/old.ff"
done
