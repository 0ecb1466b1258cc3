#!/usr/bin/env bash
# A change that must not change results, checked: builds every shared
# input (and the generated scenes) with an OLD and a NEW pair of binaries,
# as spheres and cubes, and the generated two-level scenes as PLP and BSP,
# and compares the files byte for byte; then renders two views of each
# file with both clients (--file) and compares the PNGs.
# Usage: benches/compare_outputs.sh OLD_BIN_DIR NEW_BIN_DIR [DATA_DIR]
#   (each BIN_DIR holds `farfield` and `farfield-server`, e.g. a copy of an
#   older checkout's target/release and this one's).
# Across a change of the file format (FORMATS=changed), the files cannot be
# the same and the new client cannot read the old file: each client renders
# its own build instead, and the files' sizes are listed side by side.
set -u
old=${1:?old binaries folder}; new=${2:?new binaries folder}
data=${3:-${FARFIELD_DATA:-../shared/data}}
out=$(mktemp -d)
inputs=("$data/stanford-bunny.obj" "$data/horse.ply" "$data/igea.ply" "$data/beast.obj"
  "$data/spot.obj" "$data/autzen_trim.las" "$data/2XHE.pdb" gen:tree gen:island gen:forest)
same=0; differ=0
# Builds `input` as `kind` with both, compares the files, and renders two
# views of the old file with both clients.
compare() {
  local input=$1 kind=$2 name which bin png view
  name=$(basename "$input" | tr ':' '_')
  for which in old new; do
    bin=$old; [ $which = new ] && bin=$new
    "$bin/farfield-server" build "$input" --kind $kind --out "$out/$name.$kind.$which.ff" --json >/dev/null ||
      { echo "$which build failed: $input $kind"; differ=$((differ + 1)); return; }
  done
  local newfile=$out/$name.$kind.old.ff
  if [ "${FORMATS:-same}" = changed ]; then
    newfile=$out/$name.$kind.new.ff
    echo "sizes: $input $kind: old $(stat -c %s "$out/$name.$kind.old.ff") new $(stat -c %s "$newfile") bytes"
  elif cmp -s "$out/$name.$kind.old.ff" "$out/$name.$kind.new.ff"; then same=$((same + 1)); else
    differ=$((differ + 1)); echo "files differ: $input $kind"; fi
  for view in azimuth=30,elevation=25,distance=2.5 azimuth=200,elevation=10,distance=1.5; do
    png=$out/$name.$kind.$(echo $view | tr '=,' '__')
    "$old/farfield" render --file "$out/$name.$kind.old.ff" --orbit $view --size 320x240 --out "$png.old.png" >/dev/null
    "$new/farfield" render --file "$newfile" --orbit $view --size 320x240 --out "$png.new.png" >/dev/null
    if cmp -s "$png.old.png" "$png.new.png"; then same=$((same + 1)); else
      differ=$((differ + 1)); echo "renders differ: $name $kind $view"; fi
  done
}
for input in "${inputs[@]}"; do
  for kind in spheres cubes; do
    # The cube builder takes triangles and atoms: no point clouds, and the
    # generated landscapes are too large for it here.
    case "$kind:$input" in cubes:*autzen_trim.las | cubes:gen:island | cubes:gen:forest) continue ;; esac
    compare "$input" $kind
  done
done
# The two-level kinds, on the generated scenes they were made for: PLP's
# city and cars, image caching's island and forest.
for pair in gen:city:plp gen:cars:plp gen:island:bsp gen:forest:bsp; do
  compare "${pair%:*}" "${pair##*:}"
done
echo "identical: $same, different: $differ (files in $out)"
[ $differ -eq 0 ]
