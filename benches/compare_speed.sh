#!/usr/bin/env bash
# Old against new in alternating rounds, in one run (these machines are
# noisy: only ratios taken in one run mean anything): build throughput
# (horse, igea), traversal rate and, from `farfield bench-stream`, time to
# first image, time to refined, page throughput with 1 and 16 clients and
# memory. Prints, per figure, both medians and the median of the per-round
# new/old ratios with their range.
# Usage: benches/compare_speed.sh OLD_BIN_DIR NEW_BIN_DIR [ROUNDS] [DATA_DIR]
set -euo pipefail
old=${1:?old binaries folder}; new=${2:?new binaries folder}
rounds=${3:-5}
data=${4:-${FARFIELD_DATA:-../shared/data}}
work=$(mktemp -d)
"$new/farfield-server" build gen:island --param size=1024 --param trees=128 --out "$work/island.ff" >/dev/null
log=$work/rounds.jsonl
for r in $(seq 1 "$rounds"); do
  for which in old new; do
    bin=$old; [ $which = new ] && bin=$new
    line() { echo "{\"which\":\"$which\",\"what\":\"$1\",\"r\":$2}" >>"$log"; }
    line build_horse "$("$bin/farfield-server" bench build "$data/horse.ply" --repeats 11 --json)"
    line build_igea "$("$bin/farfield-server" bench build "$data/igea.ply" --repeats 7 --json)"
    line traverse_island "$("$bin/farfield-server" bench traverse "$work/island.ff" --repeats 9 --json)"
    line stream_island "$("$bin/farfield" bench-stream "$work/island.ff" --clients 1,16 --seconds 3 --repeats 9 --json 2>/dev/null)"
  done
done
python3 - "$log" <<'PY'
import json, statistics as st, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
figures = {
    "build horse, M vertices/s": ("build_horse", lambda r: r["vertices_per_second_import_and_build"] / 1e6),
    "build igea, M vertices/s": ("build_igea", lambda r: r["vertices_per_second_import_and_build"] / 1e6),
    "traverse island, M nodes/s": ("traverse_island", lambda r: r["median_nodes_per_second"] / 1e6),
    "time to first image, ms": ("stream_island", lambda r: r["time_to_first_image_median_ms"]),
    "time to refined, ms": ("stream_island", lambda r: r["refined_ms"]),
    "1 client, MB/s": ("stream_island", lambda r: r["throughput"][0]["mb_per_s"]),
    "16 clients, MB/s": ("stream_island", lambda r: r["throughput"][1]["mb_per_s"]),
    "16 clients, peak RSS MiB": ("stream_island", lambda r: (r["throughput"][1]["rss_max_bytes"] or 0) / 2**20),
}
for name, (what, f) in figures.items():
    o = [f(r["r"]) for r in rows if r["which"] == "old" and r["what"] == what]
    n = [f(r["r"]) for r in rows if r["which"] == "new" and r["what"] == what]
    ratios = [b / a for a, b in zip(o, n) if a]
    print(f"{name}: old {st.median(o):.2f}, new {st.median(n):.2f}; new/old median {st.median(ratios):.3f} "
          f"[{min(ratios):.3f}..{max(ratios):.3f}]")
PY
