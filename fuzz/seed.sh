#!/bin/sh
# Fills fuzz/corpus/<target>/ with seeds made from the shipped files (see docs/fuzzing.md):
#   scene:    every scenes/*.toml
#   obj_mtl:  every shipped OBJ with every shipped MTL (OBJ, a 0x00 byte, MTL), each OBJ alone,
#             and a small hand-written pair
#   bare_model: every shipped OBJ with its MTL (OBJ, a 0x00 byte, MTL), `mtllib m.mtl`
#   view_script: two viewer scripts
#   solution: a solution file of the two smallest scenes the target reads against, solved with
#             `cargo run --release -- solve`, behind a selector byte (scene index; high bit set:
#             the target repairs the envelope), with and without the repair bit.
# Run from anywhere; existing corpus files are kept (libFuzzer adds its own next to them).
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
corpus=fuzz/corpus
mkdir -p "$corpus/scene" "$corpus/obj_mtl" "$corpus/solution"

for s in scenes/*.toml fuzz/tiny.toml; do
    cp "$s" "$corpus/scene/$(basename "$s")"
done

for obj in scenes/*/*.obj; do
    o=$(basename "$obj" .obj)
    cp "$obj" "$corpus/obj_mtl/$o"
    for mtl in scenes/*/*.mtl; do
        m=$(basename "$mtl" .mtl)
        { cat "$obj"; printf '\000'; cat "$mtl"; } > "$corpus/obj_mtl/$o+$m"
    done
done
{
    printf 'mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n'
    printf 'g quad\nusemtl lamp\nf 1/1/1 2/1/1 3/1/1 4/1/1\ng tri\nusemtl grey\nf 1 2 3\no pt\np 1\nl 1 2\n'
    printf '\000'
    printf 'newmtl lamp\nKd 0.5 0.5 0.5\nKe 2 2 2\n\nnewmtl grey\nKd 0.25 0.25 0.25 # c\nKa 0 0 0\n'
} > "$corpus/obj_mtl/small"

# bare_model: every shipped OBJ with its own MTL, its `mtllib` renamed to the target's m.mtl.
# view_script: two scripts of the viewer's three commands.
mkdir -p "$corpus/bare_model" "$corpus/view_script"
for obj in scenes/*/*.obj; do
    mtl=$(sed -n 's/^mtllib[[:space:]]*//p' "$obj" | head -n 1)
    {
        sed 's/^mtllib .*/mtllib m.mtl/' "$obj"
        printf '\000'
        if [ -n "$mtl" ] && [ -f "$(dirname "$obj")/$mtl" ]; then cat "$(dirname "$obj")/$mtl"; fi
    } > "$corpus/bare_model/$(basename "$obj" .obj)"
done
printf 'press forward\nhold forward,turn-left 1.5\nwait 0.25\npress direct\n# a comment\npress play\n' \
    > "$corpus/view_script/walk"
printf 'hold look-up,up 3600\n' > "$corpus/view_script/long"

# The first two scenes of fuzz_targets/solution.rs's SCENES, in its order. Not the others: the
# 190 kB solution of two-spots-narrow takes 0.5 s per run under the sanitizer (a mutant of it
# passed libFuzzer's 1 s timeout on a busy machine) and the Cornell box's is 1.7 MB; the target
# still reads the small files against those scenes.
k=0
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for s in fuzz/tiny.toml scenes/two-spots.toml; do
    nice -n 10 cargo run --release --quiet -- solve "$s" -o "$tmp/s.pfsol" --quiet
    name=$(basename "$s" .toml)
    # shellcheck disable=SC2059
    { printf "\\$(printf '%03o' $((128 + k)))"; cat "$tmp/s.pfsol"; } > "$corpus/solution/$name-repair"
    # shellcheck disable=SC2059
    { printf "\\$(printf '%03o' "$k")"; cat "$tmp/s.pfsol"; } > "$corpus/solution/$name"
    k=$((k + 1))
done
ls -l "$corpus"/*
