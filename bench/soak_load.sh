#!/usr/bin/env bash
# Soak under load on loopback: sustained streams through the services for a
# long time, recording memory and latency over time (issue 15 item 5;
# docs/BENCHMARKS.md "Soak under load"). The four services on hours of
# simulated data, CPU per second of data: bench/soak.sh.
# Two chains, each on its own domain, at once:
#   field (domain D):  bench_dds_source, the AUV 4-sensor pass cycled at its
#                      own rate (40/s: 4 gradiometers at 10 Hz; stamps = send
#                      time, so the vessel moves as in the file and comes back
#                      every 200 s) -> magnav-inverter -> magnav-tracker ->
#                      magnav record --topic track; a sink of the fixes
#   load (domain D+1): bench_dds_source at RATE_PER_S -> magnav-inverter ->
#                      bench_dds_sink (latency per 10 s, loss)
# Every 10 s the resident memory (VmRSS) of every process goes into soak.csv.
# At the end: a summary (memory at 60 s vs at the end, latency of the first and
# last windows, loss, tracks made) and soak.png (gnuplot). Loopback profile:
# nothing leaves the machine.
#   bench/soak_load.sh [RATE_PER_S=10000] [DURATION_S=600] [OUT_DIR=out/soak_load]
set -euo pipefail
cd "$(dirname "$0")/.."
RATE=${1:-10000}; DUR=${2:-600}; OUT=${3:-out/soak_load}
BIN=${MAGNAV_BUILD_DIR:-build}/bin
DATA=tests/data/reference/track_pass_auv_4sensor_fluxgate.csv
B0=$(sed -n 's/^# B0_T: *//p' "$DATA" | tr -d ' ')
D=${MAGNAV_DOMAIN_ID:-$(( $$ % 150 + 10 ))}
unset MAGNAV_DDS_PROFILES MAGNAV_DDS_PARTICIPANT MAGNAV_DOMAIN_ID
mkdir -p "$OUT"
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT
FIELD="env MAGNAV_DOMAIN_ID=$D"  # env execs the program: $! is its pid
LOAD="env MAGNAV_DOMAIN_ID=$((D + 1))"

$FIELD "$BIN/bench_dds_sink" $(( 40 * DUR )) 5 30 10 >"$OUT/field_sink.log" & fsink=$!; pids+=($fsink)
$FIELD "$BIN/magnav-inverter" --b0 "$B0" --stats-period 60 >"$OUT/field_inverter.log" 2>&1 & finv=$!; pids+=($finv)
$FIELD "$BIN/magnav-tracker" --b0 "$B0" --stats-period 60 >"$OUT/tracker.log" 2>&1 & trk=$!; pids+=($trk)
$FIELD "$BIN/magnav" record --topic track --output "$OUT/track.csv" >"$OUT/record.log" 2>&1 & rec=$!; pids+=($rec)
$LOAD "$BIN/bench_dds_sink" $(( RATE * DUR )) 5 10 10 >"$OUT/sink.log" & sink=$!; pids+=($sink)
$LOAD "$BIN/magnav-inverter" --b0 "$B0" --stats-period 60 >"$OUT/inverter.log" 2>&1 & inv=$!; pids+=($inv)
until grep -q "sink ready" "$OUT/sink.log" && grep -q "sink ready" "$OUT/field_sink.log"; do sleep 0.1; done
$FIELD "$BIN/bench_dds_source" "$DATA" 40 "$DUR" >"$OUT/field_source.log" 2>&1 & fsrc=$!; pids+=($fsrc)
$LOAD "$BIN/bench_dds_source" "$DATA" "$RATE" "$DUR" >"$OUT/source.log" 2>&1 & src=$!; pids+=($src)

rss() { awk '/^VmRSS/ { print $2 }' "/proc/$1/status" 2>/dev/null || echo 0; }
echo "t_s,inverter_kB,tracker_kB,record_kB,field_inverter_kB,sink_kB,source_kB" >"$OUT/soak.csv"
echo "# soak: field 40/s + load $RATE/s for $DUR s, $(date -u '+%F %H:%M') UTC, $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores"
t=0
while kill -0 "$src" 2>/dev/null; do
  echo "$t,$(rss $inv),$(rss $trk),$(rss $rec),$(rss $finv),$(rss $sink),$(rss $src)" >>"$OUT/soak.csv"
  sleep 10; t=$((t + 10))
done
wait "$src" "$fsrc" || true
wait "$sink" "$fsink" || true
kill -TERM "$inv" "$finv" "$trk" "$rec"; wait "$inv" "$finv" "$trk" "$rec" 2>/dev/null || true

echo "load:  $(tail -1 "$OUT/sink.log")"
echo "field: $(tail -1 "$OUT/field_sink.log")"
echo "inverter (load): $(grep 'stopping' "$OUT/inverter.log" | sed 's/.*magnav-inverter: //')"
echo "tracker: $(grep 'stopping' "$OUT/tracker.log" | sed 's/.*magnav-tracker: //')"
echo "record: $(tail -1 "$OUT/record.log")"
# Memory: at 60 s (warmed up) against the end, per process.
awk -F, 'NR == 1 { for (i = 2; i <= NF; i++) name[i] = $i; next }
         $1 == 60 { for (i = 2; i <= NF; i++) at60[i] = $i }
         { for (i = 2; i <= NF; i++) { last[i] = $i; if ($i > max[i]) max[i] = $i } }
         END { for (i = 2; i <= 7; i++) printf "%s: %d kB at 60 s, %d kB at the end (%+.1f %%), max %d kB\n",
               name[i], at60[i], last[i], at60[i] ? 100 * (last[i] - at60[i]) / at60[i] : 0, max[i] }' "$OUT/soak.csv"
awk '/^window/ { n++; w[n] = $0 } END { print "latency first window: " w[1]; print "latency last window:  " w[n] }' \
  "$OUT/sink.log"
grep '^window' "$OUT/sink.log" | awk '{ print $2 "," $6 "," $8 "," $10 }' >"$OUT/latency.csv"
if command -v gnuplot >/dev/null; then
  gnuplot <<EOF
set terminal pngcairo size 900,600 font ",10"
set output "$OUT/soak.png"
set datafile separator ","
set multiplot layout 2,1 title "magnav soak: $RATE + 40 samples/s for $DUR s (loopback)"
set ylabel "resident memory (MB)"
set key outside right
set grid
plot "$OUT/soak.csv" every ::1 using 1:(\$2/1024) with lines title "inverter (load)", \
     "" every ::1 using 1:(\$3/1024) with lines title "tracker", \
     "" every ::1 using 1:(\$4/1024) with lines title "record", \
     "" every ::1 using 1:(\$5/1024) with lines title "inverter (field)", \
     "" every ::1 using 1:(\$6/1024) with lines title "sink"
set xlabel "time (s)"
set ylabel "latency source -> inverter -> sink, load chain (ms)"
set logscale y
plot "$OUT/latency.csv" using 1:(\$2/1000) with lines title "p50", "" using 1:(\$3/1000) with lines title "p99", \
     "" using 1:(\$4/1000) with lines title "max"
unset multiplot
EOF
  echo "plot: $OUT/soak.png"
fi
