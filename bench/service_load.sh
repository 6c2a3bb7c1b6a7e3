#!/usr/bin/env bash
# Service load benchmark on loopback: source -> NODE -> sink, where NODE is the
# plain relay (baseline) and then each service given. Same rate and duration
# for all, one after the other in this run.
#   bench/service_load.sh RATE_PER_S DURATION_S [SERVICE_BIN ...]
# e.g. bench/service_load.sh 50000 60 build/bin/magnav-inverter
set -euo pipefail
cd "$(dirname "$0")/.."
RATE=${1:-50000}; DUR=${2:-60}; shift 2 || true
BIN=${MAGNAV_BUILD_DIR:-build}/bin
DATA=tests/data/reference/track_pass_auv_4sensor_fluxgate.csv
EXPECTED=$(python3 -c "print(int($RATE*$DUR))")
export MAGNAV_DOMAIN_ID=${MAGNAV_DOMAIN_ID:-$(( $$ % 200 + 10 ))}
unset MAGNAV_DDS_PROFILES MAGNAV_DDS_PARTICIPANT

run() {  # run NAME CMD...
  local name=$1; shift
  local sink_out; sink_out=$(mktemp)
  "$BIN/bench_dds_sink" "$EXPECTED" 2 5 > "$sink_out" &
  local sink=$!
  "$@" > /dev/null 2>&1 &
  local node=$!
  until grep -q "sink ready" "$sink_out"; do sleep 0.1; done
  local src; src=$("$BIN/bench_dds_source" "$DATA" "$RATE" "$DUR")
  wait "$sink"
  kill -TERM "$node"; wait "$node" || true
  echo "$name: $src | $(grep '^sink received' "$sink_out")"
  rm -f "$sink_out"
}

echo "# $(date -u +%F) $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) cores; rate $RATE/s for $DUR s; domain $MAGNAV_DOMAIN_ID"
run relay "$BIN/bench_dds_relay"
for svc in "$@"; do run "$(basename "$svc")" "$svc"; done
