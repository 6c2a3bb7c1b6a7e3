#!/usr/bin/env bash
# MCAP recordings end to end (issue 23). Loopback only.
#   a pass (the AUV fluxgate pass, 2001 samples) is replayed into
#   magnav-inverter while `magnav record --topic all --output x.mcap` records
#   every topic; then
#   python  PyPI's `mcap` reads x.mcap and pycdr2 decodes every message
#           (read_with_pypi.py: every sample and fix present, schema omgidl,
#           messages cdr). The venv is made once in VENV_DIR; when PyPI
#           cannot be reached the test is skipped (exit 77) saying so.
#   dds     `magnav info` and `magnav export` on x.mcap (the exported
#           gradiometer.csv holds the pass), and `replay --input x.mcap` into a
#           fresh inverter: its valid fixes equal `magnav invert`'s offline,
#           bit for bit. Then `replay --loop` of a 25-sample recording
#           (tests/data/bad/mcap/ok.mcap) for 3 s at --speed 4, recorded as CSV
#           (time and seq keep going up by one step across passes) and as MCAP
#           split every 20 kB (the pieces hold every sample between them).
# Usage: mcap_e2e_test.sh CASE BIN_DIR SOURCE_DIR VENV_DIR
set -euo pipefail
CASE=$1 BIN=$2 SRC=$3 VENV=$4
. "$SRC/tests/support/dds_test_lib.sh"
dds_test_setup
PASS="$SRC/tests/data/reference/track_pass_auv_1sensor_fluxgate.csv"
B0=$(sed -n 's/^# B0_T: *//p' "$PASS" | tr -d ' ')
N=$(grep -c '^[0-9]' "$PASS")

if [ "$CASE" = python ]; then
  # The venv first: no point recording if it cannot be made.
  if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c 'import mcap, pycdr2' 2>/dev/null; then
    python3 -m venv "$VENV" >"$WORK/venv.log" 2>&1 || { echo "SKIP: python3 -m venv failed: $(tail -1 "$WORK/venv.log")"; exit 77; }
    if ! timeout 300 "$VENV/bin/pip" install -q --disable-pip-version-check mcap pycdr2 >"$WORK/pip.log" 2>&1; then
      echo "SKIP: pip cannot install mcap and pycdr2 from PyPI (no network?): $(tail -1 "$WORK/pip.log")"
      exit 77
    fi
  fi
fi

# The recording: record every topic, replay the pass into an inverter.
"$BIN/magnav" record --topic all --output "$WORK/x.mcap" >"$WORK/record.log" 2>&1 &
rec=$!; pids+=($rec)
# (its stats line every 0.1 s says when it has answered every sample)
"$BIN/magnav-inverter" --b0 "$B0" --stats-period 0.1 >"$WORK/inverter1.log" 2>&1 &
inv1=$!; pids+=($inv1)
# The recorder must hear the inverter's fixes from the first: on a loaded
# machine discovery can take longer than the whole unpaced replay, and a late
# match gets only the writer's last 1000 fixes (its KEEP_LAST history).
for _ in $(seq 300); do grep -q "magnav/dipole_fix: 1 writer(s) matched" "$WORK/record.log" && break; sleep 0.1; done
grep -q "magnav/dipole_fix: 1 writer(s) matched" "$WORK/record.log" || fail "the recorder did not match the inverter's fix writer in 30 s"
"$BIN/magnav" replay --input "$PASS" --speed 0 --wait-readers 2 --wait 20 >"$WORK/replay1.log" 2>&1 ||
  fail "replay of the pass: $(tail -1 "$WORK/replay1.log")"
# The inverter answers an unpaced replay within a second or two (it was a
# fixed 3 s): once it has published a fix for every sample it stops, which
# waits for the recorder's acknowledgment of its last fixes, then the recorder
# stops. (At most 30 s; the counts below fail if it never got there.)
for _ in $(seq 300); do grep -q "magnav-inverter: $N samples .*, $N fixes," "$WORK/inverter1.log" && break; sleep 0.1; done
kill -TERM "$inv1"; wait "$inv1" 2>/dev/null || true
kill -INT "$rec"; wait "$rec" || fail "record failed: $(tail -3 "$WORK/record.log")"
[ -f "$WORK/x.mcap" ] || fail "no x.mcap"
grep -q "recorded $N gradiometer" "$WORK/record.log" || fail "record: $(grep recorded "$WORK/record.log" | tr '\n' ' ')"
grep -q "recorded $N dipole_fix" "$WORK/record.log" || fail "record: $(grep recorded "$WORK/record.log" | tr '\n' ' ')"
echo "recorded: $(grep -h 'wrote' "$WORK/record.log")"

case "$CASE" in
python)
  "$VENV/bin/python" "$SRC/tests/mcap/read_with_pypi.py" "$WORK/x.mcap" "$PASS" || fail "PyPI reader"
  ;;
dds)
  "$BIN/magnav" info "$WORK/x.mcap" >"$WORK/info.txt" 2>&1 || fail "info: $(cat "$WORK/info.txt")"
  cat "$WORK/info.txt"
  grep -q "^magnav/gradiometer (magnav::msg::GradiometerSample): $N message(s)" "$WORK/info.txt" || fail "info: gradiometer count"
  grep -q "^magnav/dipole_fix (magnav::msg::DipoleFix): $N message(s)" "$WORK/info.txt" || fail "info: dipole_fix count"
  "$BIN/magnav" export "$WORK/x.mcap" --output-dir "$WORK/csv" >"$WORK/export.log" 2>&1 || fail "export: $(cat "$WORK/export.log")"
  "$BIN/magnav" info "$WORK/csv/gradiometer.csv" >"$WORK/info_csv.txt" 2>&1 || fail "info csv: $(cat "$WORK/info_csv.txt")"
  grep -q "$N row(s)" "$WORK/info_csv.txt" || fail "info on the exported CSV: $(cat "$WORK/info_csv.txt")"
  [ "$(col "$WORK/csv/gradiometer.csv" B_x)" = "$(col "$PASS" B_x)" ] || fail "exported B_x differs from the pass"
  # The recording replayed into a fresh inverter.
  "$BIN/magnav" invert --input "$PASS" --method ted-egt --output "$WORK/offline.csv" >/dev/null
  valid_fixes "$WORK/offline.csv" >"$WORK/want.txt"
  "$BIN/magnav" record --topic dipole_fix --count "$N" --duration 60 --output "$WORK/fixes.csv" >"$WORK/record2.log" 2>&1 &
  rec2=$!; pids+=($rec2)
  "$BIN/magnav-inverter" --b0 "$B0" --stats-period 0 >"$WORK/inverter2.log" 2>&1 &
  inv2=$!; pids+=($inv2)
  "$BIN/magnav" replay --input "$WORK/x.mcap" --speed 1 --wait-readers 1 --wait 20 >"$WORK/replay2.log" 2>&1 ||
    fail "replay of x.mcap: $(tail -1 "$WORK/replay2.log")"
  grep -q "replayed $N messages ($N gradiometer)" "$WORK/replay2.log" || fail "replay: $(cat "$WORK/replay2.log")"
  wait "$rec2" || fail "record of the fixes failed"
  kill -TERM "$inv2"; wait "$inv2" 2>/dev/null || true
  valid_fixes "$WORK/fixes.csv" >"$WORK/got.txt"
  echo "replayed x.mcap: $(col "$WORK/fixes.csv" seq | wc -l) fixes, $(wc -l <"$WORK/got.txt") valid (offline $(wc -l <"$WORK/want.txt"))"
  cmp -s "$WORK/got.txt" "$WORK/want.txt" || fail "the valid fixes of the replayed recording differ from magnav invert"
  # --loop, and --split-size.
  "$BIN/magnav" record --output "$WORK/loop.csv" >"$WORK/record3.log" 2>&1 &
  rec3=$!; pids+=($rec3)
  "$BIN/magnav" record --output "$WORK/loop.mcap" --split-size 20000 >"$WORK/record4.log" 2>&1 &
  rec4=$!; pids+=($rec4)
  # The replay runs until the split recorder has started its second file
  # (not for a fixed wall time: on a loaded machine a few seconds may carry
  # too few passes to reach --split-size), at most 60 s.
  "$BIN/magnav" replay --input "$SRC/tests/data/bad/mcap/ok.mcap" --loop --speed 4 --wait-readers 2 \
    --wait 20 >"$WORK/replay3.log" 2>&1 &
  rep3=$!; pids+=($rep3)
  for _ in $(seq 600); do
    [ "$(ls "$WORK"/loop*.mcap 2>/dev/null | wc -l)" -ge 2 ] && break
    kill -0 "$rep3" 2>/dev/null || break
    sleep 0.1
  done
  sleep 0.5
  kill -INT "$rep3" 2>/dev/null || true
  rc=0; wait "$rep3" || rc=$?
  # (130: stopped by the SIGINT while sending, as here)
  [ "$rc" -eq 0 ] || [ "$rc" -eq 130 ] || fail "replay --loop: $(tail -1 "$WORK/replay3.log")"
  sleep 0.5
  kill -INT "$rec3" "$rec4"; wait "$rec3" "$rec4" || fail "record of the loop failed"
  looped=$(col "$WORK/loop.csv" seq | wc -l)
  [ "$looped" -gt 25 ] || fail "replay --loop sent $looped samples (not more than one pass of 25)"
  paste -d' ' <(col "$WORK/loop.csv" t) <(col "$WORK/loop.csv" seq) |
    awk 'NR > 1 && ($2 != s + 1 || $1 - t < 0.099 || $1 - t > 0.101) { bad = 1; print "step at row " NR ": " $0 }
         { t = $1; s = $2 } END { exit bad }' || fail "time or seq do not go on by one step across passes"
  pieces=$(ls "$WORK"/loop*.mcap | wc -l)
  [ "$pieces" -ge 2 ] || fail "--split-size 20000 made $pieces file(s)"
  split_total=0
  for f in "$WORK"/loop*.mcap; do
    n=$("$BIN/magnav" info "$f" | sed -n 's/^magnav\/gradiometer ([^)]*): \([0-9]*\) message.*/\1/p')
    split_total=$((split_total + n))
  done
  echo "replay --loop: $looped samples, time and seq continuous; --split-size: $pieces files, $split_total samples"
  [ "$split_total" -eq "$looped" ] || fail "the split files hold $split_total samples, the CSV $looped"
  ;;
*) echo "unknown case $CASE"; exit 2 ;;
esac
echo PASS
