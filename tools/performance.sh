#!/usr/bin/env bash
# Measures what docs/performance.md quotes: solve time and peak memory of every shipped scene,
# a generated 10,048-polygon building, the RRPs' storage, every method's frame time per stage at
# two sizes, the instruction-set builds against each other, walkthrough frame rates and the
# peak memory of a render per method. Raw results go to OUT (default target/performance), one
# file per measurement; the page's tables are read off them.
#
#   bash tools/performance.sh            # over 25 minutes on 2 cores: the 8 x 8 building's
#                                        # solve alone took 19 (docs/performance.md)
#   CRITERION=1 bash tools/performance.sh   # also the criterion deferred-pass benchmarks
#   PEER=1 bash tools/performance.sh        # also Mesa llvmpipe on the exported models
#                                           # (tools/peer-llvmpipe.py says what it needs)
#
# Run it on a quiet machine: every number is wall clock. Methods are compared inside one
# `bench` run (interleaved per size), instruction-set builds in alternating rounds.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-target/performance}
mkdir -p "$OUT"
cargo build --release -q
BIN=target/release/pixelflow-sim
TIME=/usr/bin/time

{
  echo "date: $(date -u +%Y-%m-%dT%H:%MZ)"
  echo "commit: $(git rev-parse --short HEAD 2>/dev/null || echo unknown)"
  echo "cores: $(nproc)"
  grep -m1 'model name' /proc/cpuinfo || true
  grep -m1 -o -w 'avx512f' /proc/cpuinfo || echo "no avx512f"
  grep -m1 -o -w 'avx2' /proc/cpuinfo || echo "no avx2"
  grep MemTotal /proc/meminfo
  rustc --version
} > "$OUT/machine.txt"

echo "solves"
: > "$OUT/solve.txt"
for s in two-spots cornell-box gallery gallery-fine; do
  for run in 1 2 3; do
    [ "$s" = gallery-fine ] && [ $run -gt 1 ] && continue
    $TIME -f "$s run $run: %e s wall, %M KB peak" \
      $BIN solve "scenes/$s.toml" -o "$OUT/$s.pfsol" 2>&1 | grep -E "solved|wall" >> "$OUT/solve.txt"
  done
done

echo "building"
$BIN generate building --rooms-x 8 --rooms-z 8 --cut 2 -o "$OUT/building/building.toml" > /dev/null 2>&1
{
  $TIME -f "check: %e s wall, %M KB peak" $BIN check "$OUT/building/building.toml" 2>&1 |
    grep -E "polygons|wall|solve"
  $TIME -f "solve: %e s wall, %M KB peak" \
    $BIN solve "$OUT/building/building.toml" -o "$OUT/building.pfsol" 2>&1 | grep -E "solved|wall"
} > "$OUT/building.txt"

echo "storage"
for s in two-spots cornell-box gallery gallery-fine; do
  $BIN stats "$OUT/$s.pfsol" --frames 0 --json > "$OUT/stats-$s.json"
done

echo "frames"
METHODS=direct,texture-nearest,texture-bilinear,texture-bicubic,mesh
for s in two-spots cornell-box gallery gallery-fine; do
  $BIN bench "$OUT/$s.pfsol" --methods $METHODS --sizes 512,1024 --frames 20 \
    > "$OUT/bench-$s.txt" 2>&1
done

echo "instruction sets"
: > "$OUT/isa.txt"
for round in 1 2 3; do
  for lanes in portable avx2 avx512; do
    for s in cornell-box gallery; do
      PIXELFLOW_SIM_LANES=$lanes $BIN bench "$OUT/$s.pfsol" \
        --methods direct,texture-bilinear,mesh --sizes 1024 --frames 20 2>/dev/null |
        awk -v l=$lanes -v s=$s -v r=$round 'NR > 2 { print r, l, s, $0 }' >> "$OUT/isa.txt"
    done
  done
done

echo "walkthroughs"
: > "$OUT/walkthrough.txt"
for s in gallery gallery-fine; do
  for m in direct texture-bilinear mesh; do
    $BIN render "$OUT/$s.pfsol" --method $m --walkthrough -o "$OUT/walk-$s-$m.png" 2>&1 |
      grep walkthrough | sed "s/^/$s $m: /" >> "$OUT/walkthrough.txt"
  done
done

echo "render memory"
: > "$OUT/render-memory.txt"
for s in two-spots cornell-box gallery gallery-fine; do
  $BIN check "scenes/$s.toml" 2>&1 | grep -E "^(frame|textures|mesh)" | sed "s/^/$s estimate: /" \
    >> "$OUT/render-memory.txt"
  for m in direct texture-bilinear mesh; do
    $TIME -f "$s $m: %e s wall, %M KB peak" \
      $BIN render "$OUT/$s.pfsol" --method $m -o "$OUT/mem-$s-$m.png" -q 2>> "$OUT/render-memory.txt"
  done
done

if [ "${PEER:-0}" = 1 ]; then
  # The same model drawn by the project and by llvmpipe from the same camera, alternately,
  # three rounds: the lightmap against texture-bilinear, the vertex-coloured mesh against mesh.
  echo "peer"
  : > "$OUT/peer.txt"
  for s in cornell-box gallery; do
    $BIN export "$OUT/$s.pfsol" -o "$OUT/peer-$s-lightmap.glb" > /dev/null
    $BIN export "$OUT/$s.pfsol" -o "$OUT/peer-$s-mesh.glb" --mesh > /dev/null
  done
  for round in 1 2 3; do
    for s in cornell-box gallery; do
      $BIN bench "$OUT/$s.pfsol" --methods texture-bilinear,mesh --sizes 1024 --frames 20 \
        2>/dev/null | awk -v s=$s -v r=$round 'NR > 3 { print r, "project", s, $1, $4 }' >> "$OUT/peer.txt"
      for kind in lightmap mesh; do
        EGL_PLATFORM=surfaceless python3 tools/peer-llvmpipe.py "$OUT/peer-$s-$kind.glb" \
          --size 1024 --frames 20 | sed "s/^/$round llvmpipe $s $kind /" >> "$OUT/peer.txt"
      done
    done
  done
fi

if [ "${CRITERION:-0}" = 1 ]; then
  echo "criterion"
  cargo bench -q -p pixelflow-bench --profile release --bench frame -- deferred > "$OUT/criterion-deferred.txt" 2>&1
fi
echo "results in $OUT"
