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
#   localizer magnav-localizer --state-dir killed 10 s into a 20 s replay of
#             the reference localize pass (1110 s of data at --speed 55) and
#             restarted 0.3 s later with the same state directory. It
#             checkpoints every 1 s (--checkpoint-period 1: the writers'
#             history of 1000 samples per sensor holds 200 s of data, 3.6 s
#             at this speed, and must reach back past the checkpoint; at the
#             default 5 s the live rate leaves 200 s of margin). Passes when
#             the restarted localizer resumed from the checkpoint, dropped
#             the history it held as "already in the checkpoint" (none
#             skipped, no "time goes backwards"), and its final estimates
#             (recorded by a recorder never restarted) have an RMS error
#             against the truth within 1.2x of the uninterrupted run's
#             (`magnav localize --method ekf-bounded`, which a live run
#             equals to 1e-9 m: LocalizerService.ReplayedAndRecorded...); the
#             largest difference from it is printed.
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
localizer)
  M="$SRC/tests/data/reference/localize_measurements.csv" G="$SRC/tests/data/reference/localize_gnss_full.csv"
  D="$SRC/tests/data/reference/localize_deployment.csv" T="$SRC/tests/data/reference/localize_truth_sensors.csv"
  "$BIN/magnav" localize --measurements "$M" --deployment "$D" --gnss "$G" --method ekf-bounded \
    --output "$WORK/offline.csv" >/dev/null
  # rms FILE: RMS horizontal error of the last estimate per sensor against the truth.
  rms() {
    awk -F, 'FNR == 1 { f++ } /^#/ { next }
             !h[f] { for (i = 1; i <= NF; i++) c[f, $i] = i; h[f] = 1; next }
             f == 1 { tx[$c[1, "sensor_id"]] = $c[1, "x"]; ty[$c[1, "sensor_id"]] = $c[1, "y"] }
             f == 2 { x[$c[2, "sensor_id"]] = $c[2, "x"]; y[$c[2, "sensor_id"]] = $c[2, "y"] }
             END { for (id in tx) { if (!(id in x)) { print "missing"; exit } s += (x[id] - tx[id]) ^ 2 + (y[id] - ty[id]) ^ 2; n++ }
                   printf "%.6f\n", sqrt(s / n) }' "$T" "$1"
  }
  # maxdiff A B: largest |difference| of x, y of the last estimate per sensor.
  maxdiff() {
    awk -F, 'FNR == 1 { f++ } /^#/ { next }
             !h[f] { for (i = 1; i <= NF; i++) c[f, $i] = i; h[f] = 1; next }
             { x[f, $c[f, "sensor_id"]] = $c[f, "x"]; y[f, $c[f, "sensor_id"]] = $c[f, "y"]; ids[$c[f, "sensor_id"]] = 1 }
             END { for (id in ids) { d = x[1, id] - x[2, id]; if (d < 0) d = -d; if (d > m) m = d
                                     d = y[1, id] - y[2, id]; if (d < 0) d = -d; if (d > m) m = d }
                   printf "%.3g\n", m }' "$1" "$2"
  }
  want=$(rms "$WORK/offline.csv")
  LOC=("$BIN/magnav-localizer" --deployment "$D" --moment-body 30000,2000,10000 --vessel-z 0 --sigma-b 1e-9
       --stats-period 0 --state-dir "$WORK/state" --checkpoint-period 1)
  for run in $(seq "$RUNS"); do
    rm -rf "$WORK/state" "$WORK/positions.csv"
    "$BIN/magnav" record --topic sensor_position --output "$WORK/positions.csv" >"$WORK/record.log" 2>&1 &
    rec=$!; pids+=($rec)
    "${LOC[@]}" >"$WORK/localizer1.log" 2>&1 &
    loc1=$!; pids+=($loc1)
    start=$(date +%s.%N)
    "$BIN/magnav" replay --magnetometer "$M" --gnss "$G" --speed 55 --wait-readers 1 --wait 20 >"$WORK/replay.log" 2>&1 &
    rp=$!; pids+=($rp)
    sleep 10
    [ -s "$WORK/state/magnav-localizer.state" ] || fail "no checkpoint written 10 s into the run"
    restart "$loc1" "$WORK/localizer2.log" "${LOC[@]}"
    loc2=$restarted
    wait "$rp" || fail "replay stopped: $(tail -1 "$WORK/replay.log")"
    took=$(echo "$(date +%s.%N) - $start" | bc)
    sleep 2
    alive "$loc2" magnav-localizer && alive "$rec" "magnav record"
    kill -TERM "$loc2"; wait "$loc2" || fail "the restarted localizer failed"
    sleep 1  # its final estimates reach the recorder
    kill -TERM "$rec"; wait "$rec" || fail "record failed"
    keep
    grep -q "resumed from checkpoint" "$WORK/localizer2.log" || fail "the restarted localizer did not resume"
    ! grep -q "time goes backwards" "$WORK/localizer2.log" || fail "history taken for 'time goes backwards'"
    read -r used skipped already < <(sed -n 's/.*stopping after \([0-9]*\) samples used, \([0-9]*\) skipped, .* \([0-9]*\) already in the.*/\1 \2 \3/p' \
                                     "$WORK/localizer2.log")
    got=$(rms "$WORK/positions.csv")
    diff=$(maxdiff "$WORK/positions.csv" "$WORK/offline.csv")
    echo "run $run: replay took ${took%???????} s; restarted localizer resumed, ${already:-?} items of the history" \
         "already in the checkpoint, ${skipped:-?} skipped, ${used:-?} used in all; final RMS error $got m" \
         "(uninterrupted $want m), largest difference from the uninterrupted estimates $diff m"
    [ "${skipped:-1}" -eq 0 ] || fail "$skipped samples skipped"
    [ "${already:-0}" -gt 0 ] || fail "no history dropped as already in the checkpoint"
    awk -v g="$got" -v w="$want" 'BEGIN { exit !(g != "missing" && g <= 1.2 * w) }' \
      || fail "final RMS error $got m, more than 1.2 x the uninterrupted $want m"
  done
  ;;
*) echo "unknown case $CASE"; exit 2 ;;
esac
echo "$RUNS passed, 0 failed"
