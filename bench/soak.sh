#!/usr/bin/env bash
# Soak of the four services on hours of simulated data (issue 22 item 6;
# docs/BENCHMARKS.md "Soak of the four services"). Three chains at once on
# loopback (the built-in magnav_loopback profile), each on its own domain:
#   field     (domain D):   magnav replay --input field_<H>h.csv (9 gradiometers
#                           at 10 Hz, a vessel crossing every 360 s) at
#                           SOAK_SPEED_FIELD x -> magnav-inverter + magnav-tracker
#   localizer (domain D+1): magnav replay of the racetrack survey (6 sensors at
#                           2 Hz + GNSS at 1 Hz) at SOAK_SPEED_LOCALIZER x ->
#                           magnav-localizer (publishing every 5 s)
#   matcher   (domain D+2): magnav replay --map-path of a path over the crustal
#                           map (1 step per second) at SOAK_SPEED_MATCHER x ->
#                           magnav-matcher (afpf, a fix every 200 m)
# Inputs: bench/soak_data.py (fixed seeds; made once into OUT). Every
# SOAK_SAMPLE_S (wall) each service's CPU time (utime + stime of
# /proc/PID/stat) and VmRSS go into OUT/<service>.csv; the replay's start and
# end give the data time of each sample. bench/soak_report.py then compares
# the first and the last hour of data: CPU s per s of data and mean RSS; a
# service whose last hour is above 1.5x its first, or that lost samples, makes
# this script exit 1 and is named. Plot: OUT/soak_services.png (gnuplot).
# SOAK_CHAINS="field localizer matcher" (the default) runs fewer if given.
# Not in CI.
#   bench/soak.sh [HOURS=3] [OUT=out/soak]
# e.g. SOAK_SPEED_FIELD=20 bench/soak.sh 3 out/soak
# The older soak under load (10,000 samples/s through an inverter for
# 10 min): bench/soak_load.sh.
set -euo pipefail
cd "$(dirname "$0")/.."
HOURS=${1:-3}; OUT=${2:-out/soak}
SPEED_FIELD=${SOAK_SPEED_FIELD:-20}; SPEED_LOC=${SOAK_SPEED_LOCALIZER:-60}; SPEED_MATCH=${SOAK_SPEED_MATCHER:-60}
SAMPLE_S=${SOAK_SAMPLE_S:-2}
CHAINS=${SOAK_CHAINS:-field localizer matcher}
has() { [[ " $CHAINS " == *" $1 "* ]]; }
SERVICES=$(for c in $CHAINS; do case $c in field) echo -n "inverter tracker ";; *) echo -n "$c ";; esac; done)
BIN=${MAGNAV_BUILD_DIR:-build}/bin
D=${MAGNAV_DOMAIN_ID:-$(( $$ % 150 + 10 ))}
unset MAGNAV_DDS_PROFILES MAGNAV_DDS_PARTICIPANT MAGNAV_DOMAIN_ID
B0=2e-05,1e-06,4.5e-05  # bench/soak_data.py's
MAP=tests/data/reference/map_crustal_anomaly.csv
F0=$(python3 -c 'import math; print(repr(math.hypot(22838.121767602996, 1452.8242542037194, 41845.01475649571)))')
mkdir -p "$OUT"
echo "# soak ($CHAINS): $HOURS h of data per chain; field ${SPEED_FIELD}x, localizer ${SPEED_LOC}x, matcher ${SPEED_MATCH}x;" \
  "$(date -u '+%F %H:%M') UTC, $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg); domains $D-$((D + 2))" \
  | tee "$OUT/summary.txt"
python3 bench/soak_data.py "$BIN/magnav" "$OUT" "$HOURS" "$CHAINS"
H=$(python3 -c "print('%g' % float('$HOURS'))")

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null || true; }
trap cleanup EXIT

# monitor NAME PID: CPU (s) and VmRSS (kB) of PID every SAMPLE_S s (wall) into OUT/NAME.csv.
monitor() {
  local name=$1 pid=$2 tick; tick=$(getconf CLK_TCK)
  echo "wall_s,cpu_s,rss_kb" >"$OUT/$name.csv"
  while kill -0 "$pid" 2>/dev/null; do
    local stat rss
    stat=$(cut -d' ' -f14,15 "/proc/$pid/stat" 2>/dev/null) || break
    rss=$(awk '/^VmRSS/ { print $2 }' "/proc/$pid/status" 2>/dev/null) || break
    echo "$(date +%s.%N),$(echo "$stat" | awk -v hz="$tick" '{ printf "%.2f", ($1 + $2) / hz }'),$rss" >>"$OUT/$name.csv"
    sleep "$SAMPLE_S"
  done
}
# replay NAME DOMAIN ARGS...: the replay, its start and end (wall) into OUT/NAME_replay.times.
replay() {
  local name=$1 domain=$2; shift 2
  local start; start=$(date +%s.%N)
  "$BIN/magnav" replay --domain "$domain" "$@" >"$OUT/${name}_replay.log" 2>&1 || echo "replay $name failed (see $OUT/${name}_replay.log)"
  echo "$start $(date +%s.%N)" >"$OUT/${name}_replay.times"
}

svc=(); rep=()
if has field; then
  env MAGNAV_DOMAIN_ID=$D "$BIN/magnav-inverter" --b0 "$B0" --stats-period 20 >"$OUT/inverter.log" 2>&1 & svc+=(inverter:$!)
  env MAGNAV_DOMAIN_ID=$D "$BIN/magnav-tracker" --b0 "$B0" --stats-period 20 >"$OUT/tracker.log" 2>&1 & svc+=(tracker:$!)
fi
if has localizer; then
  env MAGNAV_DOMAIN_ID=$((D + 1)) "$BIN/magnav-localizer" --deployment "$OUT/racetrack_deployment.csv" \
    --moment-body -15000,5000,20000 --vessel-z 0 --sigma-b 1e-9 --publish-period 5 --stats-period 20 \
    >"$OUT/localizer.log" 2>&1 & svc+=(localizer:$!)
fi
if has matcher; then
  env MAGNAV_DOMAIN_ID=$((D + 2)) "$BIN/magnav-matcher" --map "$MAP" --value-column anomaly_nT --reference-field "$F0" \
    --method afpf --fix-every 200 --stats-period 20 >"$OUT/matcher.log" 2>&1 & svc+=(matcher:$!)
fi
for s in "${svc[@]}"; do
  pids+=("${s##*:}")
  monitor "${s%%:*}" "${s##*:}" & pids+=($!)
done

if has field; then
  replay field $D --input "$OUT/field_${H}h.csv" --speed "$SPEED_FIELD" --wait-readers 2 --wait 60 & rep+=($!)
fi
if has localizer; then
  replay localizer $((D + 1)) --magnetometer "$OUT/racetrack_meas_${H}h.csv" \
    --gnss "$OUT/racetrack_gnss_${H}h.csv" --speed "$SPEED_LOC" --wait-readers 1 --wait 60 & rep+=($!)
fi
if has matcher; then
  replay matcher $((D + 2)) --map-path "$OUT/mappath_${H}h.csv" --meas-column meas_nT \
    --reference-field "$F0" --step-period 1 --speed "$SPEED_MATCH" --wait-readers 1 --wait 60 & rep+=($!)
fi
pids+=("${rep[@]}")
wait "${rep[@]}"
# Let every service drain and log its counts (stats every 20 s), then stop them.
sleep 25
for s in "${svc[@]}"; do kill -TERM "${s##*:}"; done
for s in "${svc[@]}"; do wait "${s##*:}" 2>/dev/null || true; done
sleep "$SAMPLE_S"

echo "# load at the end $(cut -d' ' -f1-3 /proc/loadavg)" | tee -a "$OUT/summary.txt"
set +e
python3 bench/soak_report.py "$OUT" "$H" "$SPEED_FIELD" "$SPEED_LOC" "$SPEED_MATCH" "$SERVICES" | tee -a "$OUT/summary.txt"
rc=${PIPESTATUS[0]}
set -e
if command -v gnuplot >/dev/null; then
  gnuplot <<EOF
set terminal pngcairo size 1000,800 font ",10" noenhanced
set output "$OUT/soak_services.png"
set datafile separator ","
set multiplot layout 2,1 title "magnav services soak: $H h of simulated data each, replayed fast on loopback (first vs last hour)"
set key outside right
set grid
set xlabel "data time (h)"
set ylabel "CPU time per second of data (s/s), 10 min windows"
set logscale y
plot for [s in "$SERVICES"] "$OUT/".s."_series.csv" every ::1 using 1:2 with linespoints pt 7 ps 0.4 title s
unset logscale y
set ylabel "resident memory VmRSS (MB)"
plot for [s in "$SERVICES"] "$OUT/".s."_series.csv" every ::1 using 1:3 with lines lw 2 title s
unset multiplot
EOF
  echo "plot: $OUT/soak_services.png"
fi
exit "$rc"
