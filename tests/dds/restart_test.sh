#!/usr/bin/env bash
# Crash and restart without loss (docs/RELIABILITY.md): kill -9 a service in
# the middle of a replayed pass and start it again, while the producer and the
# consumers keep running. Loopback only.
#
#   inverter  magnav-inverter killed 3 s into a 20 s replay (the AUV fluxgate
#             pass, 2001 samples, --speed 10: the writer's history of 1000
#             samples holds 10 s) and restarted 0.3 s later (it joins with a
#             participant index the dead one's ports do not use, shm_clean.h). Passes
#             when replay finished on its own (a dead reader did not stop it),
#             the recorder (never restarted) has exactly one fix per sample
#             (2001 rows, 2001 distinct sample seqs) and the valid fixes are
#             those of `magnav invert` on the same file, bit for bit.
#   tracker   magnav-tracker killed at pass time 80 s (in the middle of the
#             track) of a --speed 10 replay and restarted 0.3 s later, with
#             magnav-inverter running throughout. Passes when replay finished,
#             the recorder (never restarted) holds estimates from before the
#             kill and up to the end of the track after it, no (track_id, t)
#             twice, none lost (the restarted tracker's burst of estimates
#             rebuilt from the history goes out with flow control,
#             dds/queued_writer.h), and the estimates within 30 m of the
#             sensor have an RMS error below 0.5 m (uninterrupted: 0.11 m).
#             Every process must still be running when it is stopped.
# Each case runs $MAGNAV_RESTART_RUNS times (default 2; `MAGNAV_RESTART_RUNS=20`
# for the 20-in-a-row check of issue 15).
# Usage: restart_test.sh CASE BIN_DIR SOURCE_DIR
set -euo pipefail
CASE=$1 BIN=$2 SRC=$3
RUNS=${MAGNAV_RESTART_RUNS:-2}
. "$SRC/tests/support/dds_test_lib.sh"
dds_test_setup 40
PASS="$SRC/tests/data/reference/track_pass_auv_1sensor_fluxgate.csv"
TRUTH="$SRC/tests/data/reference/track_truth_auv.csv"
B0=$(sed -n 's/^# B0_T: *//p' "$PASS" | tr -d ' ')
N=$(grep -c '^[0-9]' "$PASS")

# restart PID LOG COMMAND...: kill -9 the service PID, wait
# $MAGNAV_RESTART_DELAY (0.3 s), start COMMAND again with its output in LOG;
# its pid in $restarted.
restart() {
  local pid=$1 log=$2
  shift 2
  kill -9 "$pid"; wait "$pid" 2>/dev/null || true
  sleep "${MAGNAV_RESTART_DELAY:-0.3}"
  "$@" >"$log" 2>&1 &
  restarted=$!; pids+=($restarted)
}

# alive PID NAME: fails unless PID is still running (a process that ended on
# its own is a failure of its own, not something to kill).
alive() { kill -0 "$1" 2>/dev/null || fail "$2 ended before it was stopped"; }

# With MAGNAV_TEST_KEEP=DIR each run's logs and outputs are copied to DIR/run-N.
keep() {
  [ -n "${MAGNAV_TEST_KEEP:-}" ] || return 0
  mkdir -p "$MAGNAV_TEST_KEEP/run-$run" && cp "$WORK"/*.log "$WORK"/*.csv "$MAGNAV_TEST_KEEP/run-$run/" 2>/dev/null || true
}

case "$CASE" in
inverter)
  "$BIN/magnav" invert --input "$PASS" --method ted-egt --output "$WORK/offline.csv" >/dev/null
  valid_fixes "$WORK/offline.csv" >"$WORK/want.txt"
  for run in $(seq "$RUNS"); do
    rm -f "$WORK/fixes.csv"
    "$BIN/magnav" record --topic dipole_fix --count "$N" --duration 60 --output "$WORK/fixes.csv" >"$WORK/record.log" 2>&1 &
    rec=$!; pids+=($rec)
    "$BIN/magnav-inverter" --b0 "$B0" --stats-period 0 >"$WORK/inverter1.log" 2>&1 &
    inv1=$!; pids+=($inv1)
    start=$(date +%s.%N)
    "$BIN/magnav" replay --input "$PASS" --speed 10 --wait-readers 1 --wait 20 >"$WORK/replay.log" 2>&1 &
    rp=$!; pids+=($rp)
    sleep 3
    restart "$inv1" "$WORK/inverter2.log" "$BIN/magnav-inverter" --b0 "$B0" --stats-period 0
    inv2=$restarted
    wait "$rp" || fail "replay stopped: $(tail -1 "$WORK/replay.log")"
    took=$(echo "$(date +%s.%N) - $start" | bc)
    wait "$rec" || fail "record failed"
    kill -TERM "$inv2"; wait "$inv2" 2>/dev/null || true
    rows=$(col "$WORK/fixes.csv" seq | wc -l)
    distinct=$(paste -d, <(col "$WORK/fixes.csv" sensor_id) <(col "$WORK/fixes.csv" seq) | sort -u | wc -l)
    valid_fixes "$WORK/fixes.csv" >"$WORK/got.txt"
    repeats=$(sed -n 's/^record: \([0-9]*\) repeated.*/\1/p' "$WORK/record.log")
    echo "run $run: replay took ${took%???????} s; $rows fixes recorded, $distinct distinct samples of $N;" \
         "$(wc -l <"$WORK/got.txt") valid (offline $(wc -l <"$WORK/want.txt")); ${repeats:-0} repeats written once"
    keep
    [ "$rows" -eq "$N" ] && [ "$distinct" -eq "$N" ] || fail "not exactly one fix per sample"
    cmp -s "$WORK/got.txt" "$WORK/want.txt" || fail "the valid fixes differ from magnav invert"
  done
  ;;
tracker)
  for run in $(seq "$RUNS"); do
    rm -f "$WORK/track.csv"
    "$BIN/magnav" record --topic track --output "$WORK/track.csv" >"$WORK/record.log" 2>&1 &
    rec=$!; pids+=($rec)
    "$BIN/magnav-inverter" --b0 "$B0" --stats-period 0 >"$WORK/inverter.log" 2>&1 &
    inv=$!; pids+=($inv)
    "$BIN/magnav-tracker" --b0 "$B0" --stats-period 0 >"$WORK/tracker1.log" 2>&1 &
    tr1=$!; pids+=($tr1)
    "$BIN/magnav" replay --input "$PASS" --speed 10 --wait-readers 2 --wait 20 >"$WORK/replay.log" 2>&1 &
    rp=$!; pids+=($rp)
    # Pass time 80 s: 8 s at --speed 10 after the first sample (+ the settle).
    sleep 8.3
    restart "$tr1" "$WORK/tracker2.log" "$BIN/magnav-tracker" --b0 "$B0" --stats-period 0
    tr2=$restarted
    wait "$rp" || fail "replay stopped: $(tail -1 "$WORK/replay.log")"
    sleep 2
    alive "$tr2" magnav-tracker && alive "$inv" magnav-inverter && alive "$rec" "magnav record"
    kill -TERM "$tr2" "$inv"; wait "$tr2" "$inv" 2>/dev/null || true
    kill -TERM "$rec"; wait "$rec" || fail "record failed"
    lost=$(sed -n 's/^record: \([0-9]*\) sample(s) lost.*/\1/p' "$WORK/record.log")
    read -r before after last < <(col "$WORK/track.csv" t | awk '{ if ($1 < 79) b++; else a++; if ($1 > m) m = $1 }
                                                                  END { print b + 0, a + 0, m + 0 }')
    dups=$(paste -d, <(col "$WORK/track.csv" track_id) <(col "$WORK/track.csv" t) | sort | uniq -d | wc -l)
    "$BIN/magnav" evaluate --estimate "$WORK/track.csv" --truth "$TRUTH" --max-range 30 --pass "$PASS" \
      >"$WORK/eval.log" 2>&1 || fail "evaluate: $(cat "$WORK/eval.log")"
    rms=$(sed -n 's/.*RMS[^0-9]*\([0-9.e+-]*\).*/\1/p' "$WORK/eval.log" | head -1)
    echo "run $run: $before estimates before the kill, $after after (last t = $last s), $dups repeated, ${lost:-0} lost; RMS within 30 m $rms m"
    keep
    [ "$before" -gt 0 ] && [ "$after" -gt 0 ] || fail "no estimates on one side of the restart"
    awk -v l="$last" 'BEGIN { exit !(l >= 95) }' || fail "the track did not resume to the end (last t = $last s)"
    [ "$dups" -eq 0 ] || fail "estimates repeated"
    [ -z "$lost" ] || fail "the recorder lost $lost estimates (the restarted tracker's burst overwrote them)"
    awk -v r="$rms" 'BEGIN { exit !(r != "" && r < 0.5) }' || fail "RMS $rms m"
  done
  ;;
*) echo "unknown case $CASE"; exit 2 ;;
esac
echo "$RUNS passed, 0 failed"
