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
#   tracker   magnav-tracker --state-dir (checkpoint every 1 s) killed at
#             pass time ~80 s (in the middle of the track) of a --speed 20
#             replay and restarted 0.3 s later with the same state directory
#             (no inverter: without fixes the live tracker is deterministic
#             and equals `magnav track --mode window` on the file). Passes when
#             the restarted tracker resumed from the checkpoint, dropped the
#             history it held as "already in the checkpoint" (none late), the
#             recorder (never restarted) holds estimates before and after the
#             checkpoint up to the end of the track, none twice for one
#             (track_id, t), none lost, and their RMS error within 30 m of the
#             sensor is within 1.2x of the uninterrupted run's; the largest
#             difference from the uninterrupted estimates is printed.
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
#   matcher   magnav-matcher (no checkpoint: its particle filter restarts from
#             the writers' TRANSIENT_LOCAL history) on the crustal map-matching
#             run (150 points, 3 s at --step-period 0.02; the histories of
#             1000 per key hold all of it): an uninterrupted run first, then
#             the matcher killed 2 s into the replay and restarted 0.3 s
#             later. Passes when the restarted matcher sent again some but
#             not all of the fixes (killed mid-path: the recorder writes
#             those repeats once) and the recorder (never restarted) got
#             exactly the uninterrupted run's fixes, row for row.
# Each case runs $MAGNAV_RESTART_RUNS times (default 2), $MAGNAV_RESTART_PARALLEL
# of them at the same time on their own domains (default 2: CI's two runs of
# the inverter and the localizer side by side; `MAGNAV_RESTART_RUNS=20
# MAGNAV_RESTART_PARALLEL=1` for the 20-in-a-row check of issue 15).
# Usage: restart_test.sh CASE BIN_DIR SOURCE_DIR
set -euo pipefail
CASE=$1 BIN=$2 SRC=$3
RUNS=${MAGNAV_RESTART_RUNS:-2}
PARALLEL=${MAGNAV_RESTART_PARALLEL:-2}
. "$SRC/tests/support/dds_test_lib.sh"
dds_test_setup
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

# run_all: one_run for run = 1..$RUNS, $PARALLEL at a time. Each run is a
# subshell with its own directory (WORK: a copy of what the case made before
# its runs) and, among the runs at the same time, its own domain; its output
# is printed in run order once it ended. The runs spend most of their time
# waiting on the paced replay (a few % of a core each): side by side they
# take the time of one.
run_all() {
  local r s first_failed=0
  declare -A job_of=()
  local running=()
  finish_run() {
    local rc=0
    wait "${job_of[$1]}" || rc=$?
    cat "$WORK/run-$1/run.out"
    if [ "$rc" -ne 0 ] && [ "$first_failed" -eq 0 ]; then first_failed=$1; fi
  }
  for r in $(seq "$RUNS"); do
    if [ "${#running[@]}" -ge "$PARALLEL" ]; then
      finish_run "${running[0]}"
      running=("${running[@]:1}")
    fi
    mkdir -p "$WORK/run-$r"
    find "$WORK" -maxdepth 1 -type f -exec cp {} "$WORK/run-$r/" \;
    (
      run=$r WORK="$WORK/run-$r" pids=()
      dds_claim_domain || exit 1  # each run its own domain, held while the run lasts
      trap 'for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done; wait 2>/dev/null || true' EXIT
      one_run
    ) >"$WORK/run-$r/run.out" 2>&1 &
    job_of[$r]=$!
    running+=("$r")
  done
  for r in "${running[@]}"; do finish_run "$r"; done
  [ "$first_failed" -eq 0 ] || { echo "FAIL: run $first_failed failed"; exit 1; }
}

# With MAGNAV_TEST_KEEP=DIR each run's logs and outputs are copied to DIR/run-N.
keep() {
  [ -n "${MAGNAV_TEST_KEEP:-}" ] || return 0
  mkdir -p "$MAGNAV_TEST_KEEP/run-$run" && cp "$WORK"/*.log "$WORK"/*.csv "$MAGNAV_TEST_KEEP/run-$run/" 2>/dev/null || true
}

case "$CASE" in
inverter)
  "$BIN/magnav" invert --input "$PASS" --method ted-egt --output "$WORK/offline.csv" >/dev/null
  valid_fixes "$WORK/offline.csv" >"$WORK/want.txt"
  one_run() {
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
  }
  ;;
tracker)
  evaluate() {
    "$BIN/magnav" evaluate --estimate "$1" --truth "$TRUTH" --max-range 30 --pass "$PASS" >"$WORK/eval.log" 2>&1 \
      || fail "evaluate: $(cat "$WORK/eval.log")"
    sed -n 's/.*RMS[^0-9]*\([0-9.e+-]*\).*/\1/p' "$WORK/eval.log" | head -1
  }
  # maxdiff A B: largest |difference| of x, y, z between rows of equal (track_id, t), and how many rows of B have none in A.
  maxdiff() {
    awk -F, 'FNR == 1 { f++ } /^#/ { next }
             !h[f] { for (i = 1; i <= NF; i++) c[f, $i] = i; h[f] = 1; next }
             { k = $c[f, "track_id"] "," $c[f, "t"] }
             f == 1 { x[k] = $c[1, "x"]; y[k] = $c[1, "y"]; z[k] = $c[1, "z"]; next }
             !(k in x) { miss++; next }
             { n++; for (j = 0; j < 3; j++) { d = (j == 0 ? $c[2, "x"] - x[k] : j == 1 ? $c[2, "y"] - y[k] : $c[2, "z"] - z[k])
                                              if (d < 0) d = -d; if (d > m) m = d } }
             END { printf "%.3g m over %d rows (%d rows without a match)\n", m, n, miss }' "$1" "$2"
  }
  # (--state-dir "$WORK/state" is added where it starts: each run has its own WORK)
  TRK=("$BIN/magnav-tracker" --b0 "$B0" --stats-period 0 --checkpoint-period 0.25)
  REPLAY=("$BIN/magnav" replay --input "$PASS" --speed 40 --wait-readers 1 --wait 20)
  # The uninterrupted run (no inverter: without fixes the live tracker is deterministic).
  "$BIN/magnav" record --topic track --output "$WORK/want.csv" >"$WORK/record0.log" 2>&1 &
  rec=$!; pids+=($rec)
  "${TRK[@]}" --state-dir "$WORK/state" >"$WORK/tracker0.log" 2>&1 &
  tr0=$!; pids+=($tr0)
  "${REPLAY[@]}" >"$WORK/replay0.log" 2>&1 || fail "replay: $(tail -1 "$WORK/replay0.log")"
  sleep 0.5
  kill -TERM "$tr0"; wait "$tr0" || fail "the uninterrupted tracker failed"
  sleep 0.5
  kill -TERM "$rec"; wait "$rec" || fail "record failed"
  want=$(evaluate "$WORK/want.csv")
  one_run() {
    rm -rf "$WORK/track.csv" "$WORK/state"
    "$BIN/magnav" record --topic track --output "$WORK/track.csv" >"$WORK/record.log" 2>&1 &
    rec=$!; pids+=($rec)
    "${TRK[@]}" --state-dir "$WORK/state" >"$WORK/tracker1.log" 2>&1 &
    tr1=$!; pids+=($tr1)
    "${REPLAY[@]}" >"$WORK/replay.log" 2>&1 &
    rp=$!; pids+=($rp)
    # Killed in the middle of the track (it runs from t = 67 s to 135 s): 0.6 s (24 s of data at --speed 40)
    # after the tracker logged its start.
    for _ in $(seq 200); do grep -q "track 1 started" "$WORK/tracker1.log" && break; sleep 0.05; done
    sleep 0.6
    [ -s "$WORK/state/magnav-tracker.state" ] || fail "no checkpoint written before the kill"
    restart "$tr1" "$WORK/tracker2.log" "${TRK[@]}" --state-dir "$WORK/state"
    tr2=$restarted
    wait "$rp" || fail "replay stopped: $(tail -1 "$WORK/replay.log")"
    sleep 0.5
    alive "$tr2" magnav-tracker && alive "$rec" "magnav record"
    kill -TERM "$tr2"; wait "$tr2" || fail "the restarted tracker failed"
    sleep 0.5  # its last estimates reach the recorder
    kill -TERM "$rec"; wait "$rec" || fail "record failed"
    keep
    grep -q "resumed from checkpoint" "$WORK/tracker2.log" || fail "the restarted tracker did not resume"
    resumed=$(sed -n 's/.*consumed up to t = \([0-9.]*\) s.*/\1/p' "$WORK/tracker2.log" | head -1)
    read -r late already < <(sed -n 's/.*stopping after [0-9]* samples ([0-9]* repeated, [0-9]* missing, \([0-9]*\) late, [0-9]* wild stamps or seqs, \([0-9]*\) already in the.*/\1 \2/p' \
                             "$WORK/tracker2.log")
    lost=$(sed -n 's/^record: \([0-9]*\) sample(s) lost.*/\1/p' "$WORK/record.log")
    read -r before after last < <(col "$WORK/track.csv" t | awk -v r="${resumed:-0}" '{ if ($1 <= r) b++; else a++; if ($1 > m) m = $1 }
                                                                                    END { print b + 0, a + 0, m + 0 }')
    dups=$(paste -d, <(col "$WORK/track.csv" track_id) <(col "$WORK/track.csv" t) | sort | uniq -d | wc -l)
    got=$(evaluate "$WORK/track.csv")
    diff=$(maxdiff "$WORK/want.csv" "$WORK/track.csv")
    rows=$(col "$WORK/track.csv" t | wc -l) want_rows=$(col "$WORK/want.csv" t | wc -l)
    echo "run $run: resumed at t = ${resumed:-?} s; ${already:-?} samples of the history already in the checkpoint," \
         "${late:-?} late; $before estimates up to the checkpoint, $after after (last t = $last s), $dups repeated," \
         "${lost:-0} lost; $rows estimates (uninterrupted $want_rows); RMS within 30 m $got m (uninterrupted $want m);" \
         "largest difference from the uninterrupted estimates $diff"
    [ "${late:-1}" -eq 0 ] || fail "$late samples dropped as late"
    [ "${already:-0}" -gt 0 ] || fail "no history dropped as already in the checkpoint"
    [ "$before" -gt 0 ] && [ "$after" -gt 0 ] || fail "no estimates on one side of the checkpoint"
    [ "$rows" -eq "$want_rows" ] || fail "$rows estimates, the uninterrupted run gave $want_rows"
    awk -v l="$last" 'BEGIN { exit !(l >= 95) }' || fail "the track did not resume to the end (last t = $last s)"
    [ "$dups" -eq 0 ] || fail "estimates repeated"
    [ -z "$lost" ] || fail "the recorder lost $lost estimates"
    awk -v g="$got" -v w="$want" 'BEGIN { exit !(g != "" && g <= 1.2 * w) }' \
      || fail "RMS within 30 m $got m, more than 1.2 x the uninterrupted $want m"
  }
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
  one_run() {
    LOC=("$BIN/magnav-localizer" --deployment "$D" --moment-body 30000,2000,10000 --vessel-z 0 --sigma-b 1e-9
         --stats-period 0 --state-dir "$WORK/state" --checkpoint-period 1)
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
  }
  ;;
matcher)
  MAP="$SRC/tests/data/reference/map_crustal_anomaly.csv"
  MPATH="$SRC/tests/data/reference/mappath_crustal_off0p1deg_noise3nT.csv"
  # |F0| of the crustal map (tests/data/reference/README.md §4b), as the service test gives it.
  # rows FILE: the data rows of a recorded CSV, sorted.
  rows() { grep -v '^#' "$1" | tail -n +2 | sort; }
  REF=$(awk 'BEGIN { printf "%.17g", sqrt(22838.121767602996 ^ 2 + 1452.8242542037194 ^ 2 + 41845.01475649571 ^ 2) }')
  MATCH=("$BIN/magnav-matcher" --map "$MAP" --value-column anomaly_nT --reference-field "$REF" --method afpf
         --seed 7 --stats-period 0)
  REPLAY=("$BIN/magnav" replay --map-path "$MPATH" --reference-field "$REF" --step-period 0.02 --speed 1
          --wait-readers 1 --wait 20)
  # The uninterrupted run: its fixes are what the restarted one must give.
  "$BIN/magnav" record --topic map_fix --duration 30 --output "$WORK/want.csv" >"$WORK/record0.log" 2>&1 &
  rec=$!; pids+=($rec)
  "${MATCH[@]}" >"$WORK/matcher0.log" 2>&1 &
  m0=$!; pids+=($m0)
  "${REPLAY[@]}" >"$WORK/replay0.log" 2>&1 || fail "replay: $(tail -1 "$WORK/replay0.log")"
  sleep 0.5
  kill -TERM "$m0"; wait "$m0" || fail "the uninterrupted matcher failed"
  kill -TERM "$rec"; wait "$rec" || fail "record failed"
  want=$(col "$WORK/want.csv" t | wc -l)
  [ "$want" -ge 5 ] || fail "the uninterrupted run gave $want fixes"
  one_run() {
    rm -f "$WORK/fixes.csv"
    "$BIN/magnav" record --topic map_fix --count "$want" --duration 30 --output "$WORK/fixes.csv" >"$WORK/record.log" 2>&1 &
    rec=$!; pids+=($rec)
    "${MATCH[@]}" >"$WORK/matcher1.log" 2>&1 &
    m1=$!; pids+=($m1)
    "${REPLAY[@]}" >"$WORK/replay.log" 2>&1 &
    rp=$!; pids+=($rp)
    # Killed mid-path (the path takes 3 s at 0.02 s a step, after discovery and the replay's settle).
    sleep 2
    restart "$m1" "$WORK/matcher2.log" "${MATCH[@]}"
    m2=$restarted
    wait "$rp" || fail "replay stopped: $(tail -1 "$WORK/replay.log")"
    wait "$rec" || fail "record did not get $want fixes"
    alive "$m2" magnav-matcher
    kill -TERM "$m2"; wait "$m2" || fail "the restarted matcher failed"
    keep
    steps=$(sed -n 's/.* \([0-9]*\) steps (.*/\1/p' "$WORK/matcher2.log" | tail -1)
    repeats=$(sed -n 's/^record: \([0-9]*\) repeated.*/\1/p' "$WORK/record.log")
    echo "run $run: $(col "$WORK/fixes.csv" t | wc -l) fixes recorded (uninterrupted $want), ${repeats:-0} of them" \
         "sent again by the restarted matcher (written once: they were sent before the kill); the restarted matcher" \
         "made ${steps:-?} steps from the writers' history and the live stream"
    # Mid-path: the first matcher had sent some fixes (the restarted one sent them again), not all.
    [ "${repeats:-0}" -gt 0 ] && [ "${repeats:-0}" -lt "$want" ] || fail "${repeats:-0} repeated of $want: not killed mid-path"
    cmp -s <(rows "$WORK/fixes.csv") <(rows "$WORK/want.csv") \
      || fail "the fixes differ from the uninterrupted run's: $(diff <(rows "$WORK/fixes.csv") <(rows "$WORK/want.csv") | head -4)"
  }
  ;;
*) echo "unknown case $CASE"; exit 2 ;;
esac
run_all
echo "$RUNS passed, 0 failed"
