#!/usr/bin/env bash
# Service load benchmark on loopback: source -> NODE -> sink, where NODE is the
# plain relay (baseline) and then each service given, one after the other in
# this run, in two phases:
#   throughput: RATE_PER_S for DURATION_S (sustained rate, loss, latency under load)
#   latency:    LAT_RATE_PER_S (default 1000) for LAT_DURATION_S (default 20):
#               the hop latency without queueing, so the service's own cost shows
#   bench/service_load.sh RATE_PER_S DURATION_S [SERVICE_BIN ...]
# e.g. bench/service_load.sh 50000 60 "build/bin/magnav-inverter --b0 2e-05,1e-06,4.5e-05"
# BENCH_SINGLE_READER=1 also runs the relay with its profile's reader alone
# and with the any-writer companion made at the start, to measure what the
# companion costs.
# Each line ends with the node's CPU time over the run (user + system, s).
# Every process uses the built-in magnav_loopback profile, unless BENCH_DDS_PROFILES=FILE and
# BENCH_DDS_PARTICIPANT=NAME give another for all of them, e.g. DDS Security:
#   scripts/make_security /tmp/sec && BENCH_DDS_PROFILES=/tmp/sec/security.xml \
#     BENCH_DDS_PARTICIPANT=magnav_secure_service bench/service_load.sh 50000 60 "..."
set -euo pipefail
cd "$(dirname "$0")/.."
RATE=${1:-50000}; DUR=${2:-60}; shift 2 || true
SERVICES=("$@")
BIN=${MAGNAV_BUILD_DIR:-build}/bin
DATA=tests/data/reference/track_pass_auv_4sensor_fluxgate.csv
LAT_RATE=${LAT_RATE:-1000}; LAT_DUR=${LAT_DUR:-20}
export MAGNAV_DOMAIN_ID=${MAGNAV_DOMAIN_ID:-$(( $$ % 200 + 10 ))}
unset MAGNAV_DDS_PROFILES MAGNAV_DDS_PARTICIPANT
if [ -n "${BENCH_DDS_PROFILES:-}" ]; then
  export MAGNAV_DDS_PROFILES=$BENCH_DDS_PROFILES
  export MAGNAV_DDS_PARTICIPANT=${BENCH_DDS_PARTICIPANT:?BENCH_DDS_PARTICIPANT must name a participant profile of $BENCH_DDS_PROFILES}
fi

run() {  # run NAME RATE DURATION CMD...
  local name=$1 rate=$2 dur=$3; shift 3
  local expected=$(( ${rate%.*} * ${dur%.*} ))
  local sink_out; sink_out=$(mktemp)
  "$BIN/bench_dds_sink" "$expected" 2 5 > "$sink_out" &
  local sink=$!
  "$@" > /dev/null 2>&1 &
  local node=$!
  until grep -q "sink ready" "$sink_out"; do sleep 0.1; done
  local src; src=$("$BIN/bench_dds_source" "$DATA" "$rate" "$dur")
  wait "$sink"
  # The node's CPU time (user + system, s) over the run, from /proc.
  local ticks; ticks=$(awk '{print $14 + $15}' "/proc/$node/stat" 2>/dev/null || echo 0)
  local cpu; cpu=$(awk -v t="$ticks" -v hz="$(getconf CLK_TCK)" 'BEGIN { printf "%.2f", t / hz }')
  kill -TERM "$node"; wait "$node" || true
  echo "$name @ $rate/s: $src | $(grep '^sink received' "$sink_out") | node CPU ${cpu} s"
  rm -f "$sink_out"
}

echo "# $(date -u '+%F %H:%M') UTC, $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores, load $(cut -d' ' -f1 /proc/loadavg); domain $MAGNAV_DOMAIN_ID; profile ${MAGNAV_DDS_PARTICIPANT:-magnav_loopback}"
for phase in "$RATE $DUR" "$LAT_RATE $LAT_DUR"; do
  set -- $phase "${SERVICES[@]}"
  run relay "$1" "$2" "$BIN/bench_dds_relay"
  # What the any-writer companion reader (node.h) costs: the same relay with
  # the profile's reader alone, and with the companion made from the start
  # (as in a field where a stock writer shares the topic).
  if [ -n "${BENCH_SINGLE_READER:-}" ]; then
    run relay-single-reader "$1" "$2" "$BIN/bench_dds_relay" single-reader
    run relay-with-companion "$1" "$2" "$BIN/bench_dds_relay" companion
  fi
  for svc in "${SERVICES[@]}"; do run "$(basename "${svc%% *}")" "$1" "$2" $svc; done
done
