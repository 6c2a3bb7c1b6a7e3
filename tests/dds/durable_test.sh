#!/usr/bin/env bash
# Durable estimates (docs/RELIABILITY.md): magnav-tracker with
# config/durable/magnav-tracker.xml (estimate writer TRANSIENT, SQLite) tracks
# a pass and stops; it is started again with no data coming; a recorder started
# after that gets the last 10 estimates of the first process, equal to what that
# process published. Without the durable profile the same recorder gets none
# (TRANSIENT_LOCAL history dies with its process). The live recording's
# `state` column says confirmed or coasting on every row. Loopback only.
# Usage: durable_test.sh BIN_DIR SOURCE_DIR
set -euo pipefail
BIN=$1 SRC=$2
. "$SRC/tests/support/dds_test_lib.sh"
dds_test_setup
PASS="$SRC/tests/data/reference/track_pass_auv_1sensor_fluxgate.csv"
B0=$(sed -n 's/^# B0_T: *//p' "$PASS" | tr -d ' ')
# The database in memory (/dev/shm, where there is one): every estimate is an
# SQLite commit, and on a disk other jobs keep busy the fsyncs made the first
# tracker take 37 s to stop (0.7 s here). What is tested is the same: the
# estimates outlive the process through the file.
DB_DIR=$(mktemp -d -p /dev/shm 2>/dev/null || mktemp -d -p "$WORK")
trap 'dds_test_cleanup; rm -rf "$DB_DIR"' EXIT
sed "s|/var/lib/magnav/magnav-tracker.db|$DB_DIR/tracker.db|" "$SRC/config/durable/magnav-tracker.xml" >"$WORK/durable.xml"

# wait_for TEXT FILE: until FILE holds TEXT, at most 20 s (the checks after it
# fail if it never does).
wait_for() { for _ in $(seq 400); do grep -q "$1" "$2" 2>/dev/null && return 0; sleep 0.05; done; }

# run PROFILE_ARGS... : track the pass, stop, restart, record late -> prints the recorded t column
run() {
  rm -f "$WORK/live.csv" "$WORK/late.csv"
  "$BIN/magnav" record --topic track --output "$WORK/live.csv" >"$WORK/live.log" 2>&1 & local rec=$!; pids+=($rec)
  "$BIN/magnav-tracker" --b0 "$B0" --stats-period 0 "$@" >"$WORK/tracker1.log" 2>&1 & local t1=$!; pids+=($t1)
  "$BIN/magnav" replay --input "$PASS" --speed 0 --wait-readers 1 --wait 20 >"$WORK/replay.log" 2>&1
  # The pass is tracked to its end: the track is lost when the vessel has gone.
  wait_for "track 1 ended" "$WORK/tracker1.log"
  kill -TERM "$t1"; wait "$t1" || true
  kill -TERM "$rec"; wait "$rec" || true
  "$BIN/magnav-tracker" --b0 "$B0" --stats-period 0 "$@" >"$WORK/tracker2.log" 2>&1 & local t2=$!; pids+=($t2)
  # Up (its writers made, the durable one from the database) before the late recorder starts.
  wait_for "on domain" "$WORK/tracker2.log"
  "$BIN/magnav" record --topic track --duration 3 --output "$WORK/late.csv" >"$WORK/late.log" 2>&1
  kill -TERM "$t2"; wait "$t2" || true
}
tcol() { awk -F, '/^#/ { next } !h { h = 1; next } { print $1 }' "$1" 2>/dev/null; }

# --out-of-reach 0: the track coasts on its misses before it ends (with the
# default end rule, since 2026-11-26, it ends "out_of_reach" 2 s after the
# vessel leaves the one sensor's reach, and no row says coasting), so both
# words of the wire's state are checked below.
run --dds-profiles "$WORK/durable.xml" --out-of-reach 0
want=$(tcol "$WORK/live.csv" | tail -10 | tr '\n' ' ')
got=$(tcol "$WORK/late.csv" | sort -n | tr '\n' ' ')
echo "durable: the first process published $(tcol "$WORK/live.csv" | wc -l) estimates; after its restart a late recorder got $(tcol "$WORK/late.csv" | wc -l): t = $got"
[ -n "$want" ] && [ "$got" = "$want" ] || { echo "FAIL: expected the last 10 estimates, t = $want"; cat "$WORK"/*.log | tail -20; exit 1; }
cmp -s <(grep -v '^#' "$WORK/live.csv" | tail -10 | sort) <(grep -v '^#' "$WORK/late.csv" | tail -n +2 | sort) \
  || { echo "FAIL: the late estimates differ from those published"; exit 1; }

# The recorder's `state` column (TrackEstimate.state, magnav track's words):
# every live estimate says confirmed or coasting, both occur (the track coasts
# on its misses before it ends), and the words are the ones of the wire.
states=$(awk -F, '/^#/ { next } !h { for (i = 1; i <= NF; ++i) if ($i == "state") c = i; h = 1; next }
                  { print (c ? $c : "no-column") }' "$WORK/live.csv" | sort | uniq -c | tr -s ' ' | tr '\n' ';')
echo "recorded states: $states"
grep -q "no-column" <<<"$states" && { echo "FAIL: the recorded track CSV has no state column"; exit 1; }
[ -z "$(awk -F, '/^#/ { next } !h { for (i = 1; i <= NF; ++i) if ($i == "state") c = i; h = 1; next }
               $c != "confirmed" && $c != "coasting" { print NR ": " $c }' "$WORK/live.csv")" ] ||
  { echo "FAIL: a recorded estimate whose state is neither confirmed nor coasting: $states"; exit 1; }
grep -q " confirmed" <<<"$states" && grep -q " coasting" <<<"$states" ||
  { echo "FAIL: expected both confirmed and coasting estimates: $states"; exit 1; }

run
n=$(tcol "$WORK/late.csv" | wc -l)
echo "not durable (built-in TRANSIENT_LOCAL): after the restart a late recorder got $n"
[ "$n" -eq 0 ] || { echo "FAIL: estimates of a process that has ended should be gone without the durable profile"; exit 1; }
echo "1 passed, 0 failed"
