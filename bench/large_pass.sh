#!/usr/bin/env bash
# Offline commands on a large pass: time and peak memory (RSS) of `magnav
# track` (batch and window) and `magnav invert` on a simulated pass of ROWS
# rows (default 1,000,001: one gradiometer at 10 Hz for 27.8 h, a vessel
# passing it in the first two minutes), and each peak as a multiple of the
# file's size (the host-independent figure). docs/BENCHMARKS.md, "Large passes".
# Usage: bench/large_pass.sh [BIN_DIR] [ROWS]
set -euo pipefail
BIN=${1:-build/bin}
ROWS=${2:-1000001}
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
seconds=$(( (ROWS - 1) / 10 ))
"$BIN/magnav" simulate --noise fluxgate --turns "$seconds:0" --sensors 0,0,0 --output "$WORK/pass.csv" \
  --truth "$WORK/truth.csv" >/dev/null
size=$(stat -c %s "$WORK/pass.csv")
echo "pass: $ROWS rows, $((size / 1000000)) MB"
measure() {
  local name=$1; shift
  /usr/bin/time -f "%e %M" -o "$WORK/time" "$@" >/dev/null 2>&1
  read -r s kb <"$WORK/time"
  awk -v n="$name" -v s="$s" -v kb="$kb" -v f="$size" \
    'BEGIN { printf "%-14s %6.2f s  %5.0f MB peak  %.2f x the file\n", n, s, kb / 1000, kb * 1000 / f }'
}
measure "track batch" "$BIN/magnav" track --input "$WORK/pass.csv" --output "$WORK/track.csv"
measure "track window" "$BIN/magnav" track --mode window --input "$WORK/pass.csv" --output "$WORK/window.csv"
measure "invert" "$BIN/magnav" invert --method ted-egt --input "$WORK/pass.csv" --output "$WORK/fixes.csv"
