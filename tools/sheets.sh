#!/bin/sh
# Picture sheets of every builtin scene: one early, one middle and the final frame side by side,
# written to renders/sheet-<scene>.png, plus the golden-hour backlit frame
# (renders/duck-golden-hour.png). Run from the repository root after `cargo build --release`:
#   sh tools/sheets.sh
# Needs ImageMagick's `convert`; bunny and horse need ../shared/models (skipped otherwise).
# Frames go to /tmp/nephele-sheets (the scenes' own output folders are left alone).
set -e
bin=./target/release/nephele
out=/tmp/nephele-sheets
for scene in duck-diffusion duck-aggregation torus-knot-aggregation bunny-aggregation horse-diffusion; do
    file=scenes/$scene.ron
    if ! $bin render "$file" --frames 1..1 --output "$out/$scene" >/dev/null 2>&1; then
        echo "skipping $scene (its target is not available here)"
        continue
    fi
    total=$(ls "$out/$scene"/*_0001.png >/dev/null && grep -o 'seconds: [0-9.]*' "$file" | head -1 | cut -d' ' -f2)
    fps=$(grep -o 'fps: [0-9.]*' "$file" | head -1 | cut -d' ' -f2)
    n=$(awk "BEGIN { printf \"%d\", $total * $fps + 0.5 }")
    early=$(awk "BEGIN { printf \"%d\", $n * 0.2 + 1 }")
    middle=$(awk "BEGIN { printf \"%d\", $n * 0.55 }")
    for f in $early $middle $n; do
        $bin render "$file" --frames "$f..$f" --output "$out/$scene" >/dev/null
    done
    name=$(basename "$file" .ron)
    p() { printf '%s/%s/%s_%04d.png' "$out" "$scene" "$name" "$1"; }
    convert "$(p "$early")" "$(p "$middle")" "$(p "$n")" +append "renders/sheet-$scene.png"
    echo "renders/sheet-$scene.png: frames $early, $middle, $n of $n"
done
$bin render scenes/duck-golden-hour.ron --frames 96..96 --output "$out/golden" >/dev/null
cp "$out/golden/duck-golden-hour_0096.png" renders/duck-golden-hour.png
echo "renders/duck-golden-hour.png"
