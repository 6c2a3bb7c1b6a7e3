#!/usr/bin/env bash
# magnav-localizer against its age (issue 22 item 2; docs/BENCHMARKS.md
# "Localizer at an age"): a racetrack survey over the held-out field of
# tests/localizer/racetrack.h (6 sensors at 25 m, 2 Hz, GNSS σ 2 m at 1 Hz;
# `magnav simulate`) for HOURS of data, replayed at SPEED× through the
# service with --method METHOD (ekf-bounded, the default, or ekf, the
# whole-pass bound of before), publishing every 5 s (wall). Every 5 s the
# service's CPU (utime + stime from /proc) and VmRSS go into
# OUT/age_METHOD.csv; at the end the first and last quarter are compared.
# Loopback profile: nothing leaves the machine.
#   bench/localizer_age.sh [METHOD=ekf-bounded] [HOURS=2] [SPEED=60] [OUT=out/localizer_age]
set -euo pipefail
cd "$(dirname "$0")/.."
METHOD=${1:-ekf-bounded}; HOURS=${2:-2}; SPEED=${3:-60}; OUT=${4:-out/localizer_age}
BIN=${MAGNAV_BUILD_DIR:-build}/bin
D=${MAGNAV_DOMAIN_ID:-$(( $$ % 150 + 10 ))}
unset MAGNAV_DDS_PROFILES MAGNAV_DDS_PARTICIPANT MAGNAV_DOMAIN_ID
mkdir -p "$OUT"
if [ ! -f "$OUT/meas_${HOURS}h.csv" ]; then
  turns=$(python3 -c "
import math
loop = 400 + 40 * math.pi
n = math.ceil($HOURS * 3600 / loop)
print(','.join(['200:0', '%.12f:0.05' % (20 * math.pi)] * (2 * n)))")
  "$BIN/magnav" simulate --output "$OUT/pass.csv" --truth "$OUT/truth.csv" --sigma-b 1e-9 \
    --moment-body -15000,5000,20000 --start -250,-60,0 --speed 2.5 --heading 0 --turns "$turns" \
    --sensors "-80,-40,25;0,-70,25;70,-30,25;-40,15,25;40,20,25;100,30,25" --rate 2 --b0 0,0,0 --seed 100 >/dev/null
  python3 - "$OUT" "$HOURS" <<'PY'
import csv, random, sys
out, hours = sys.argv[1], float(sys.argv[2])
end = hours * 3600
rng = random.Random(101)
with open(f"{out}/pass.csv") as f, open(f"{out}/meas_{sys.argv[2]}h.csv", "w") as m:
    m.write("# moment_body_Am2: -15000, 5000, 20000\n# vessel_z_m: 0\n# sigma_B_T: 1e-9\nt,sensor_id,B_x,B_y,B_z\n")
    for row in csv.DictReader(l for l in f if not l.startswith("#")):
        if float(row["t"]) <= end:
            m.write(f'{row["t"]},{row["sensor_id"]},{row["B_x"]},{row["B_y"]},{row["B_z"]}\n')
with open(f"{out}/truth.csv") as f, open(f"{out}/gnss_{sys.argv[2]}h.csv", "w") as g:
    g.write("t,x,y,sigma\n")
    for row in csv.DictReader(l for l in f if not l.startswith("#")):
        t = float(row["t"])
        if t <= end and abs(t - round(t)) < 1e-9:
            g.write(f'{row["t"]},{float(row["x"]) + rng.gauss(0, 2)},{float(row["y"]) + rng.gauss(0, 2)},2\n')
with open(f"{out}/deployment.csv", "w") as d:
    d.write("sensor_id,x,y,z,sigma_xy\n")
    for j, (x, y) in enumerate([(-80, -40), (0, -70), (70, -30), (-40, 15), (40, 20), (100, 30)]):
        d.write(f"{j},{x + rng.gauss(0, 10)},{y + rng.gauss(0, 10)},25,10\n")
PY
fi
export MAGNAV_DOMAIN_ID=$D
"$BIN/magnav-localizer" --deployment "$OUT/deployment.csv" --moment-body -15000,5000,20000 --vessel-z 0 \
  --sigma-b 1e-9 --method "$METHOD" --publish-period 5 --stats-period 0 >"$OUT/service_$METHOD.log" 2>&1 & svc=$!
trap 'kill $svc 2>/dev/null || true' EXIT
tick=$(getconf CLK_TCK)
echo "wall_s,cpu_s,rss_kb" >"$OUT/age_$METHOD.csv"
(
  start=$(date +%s.%N)
  while kill -0 $svc 2>/dev/null; do
    read -r ut st < <(awk '{print $14, $15}' /proc/$svc/stat 2>/dev/null) || break
    rss=$(awk '/VmRSS/ {print $2}' /proc/$svc/status 2>/dev/null) || break
    echo "$(echo "$(date +%s.%N) - $start" | bc),$(echo "($ut + $st) / $tick" | bc -l),$rss" >>"$OUT/age_$METHOD.csv"
    sleep 5
  done
) & mon=$!
"$BIN/magnav" replay --magnetometer "$OUT/meas_${HOURS}h.csv" --gnss "$OUT/gnss_${HOURS}h.csv" --speed "$SPEED" \
  --wait-readers 1 >"$OUT/replay_$METHOD.log" 2>&1
sleep 6
kill -TERM $svc; wait $svc || true; wait $mon || true
python3 - "$OUT/age_$METHOD.csv" "$METHOD" "$HOURS" "$SPEED" <<'PY'
import csv, sys
rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["rss_kb"]]
t = [float(r["wall_s"]) for r in rows]; c = [float(r["cpu_s"]) for r in rows]; m = [int(r["rss_kb"]) for r in rows]
n = len(rows); q = max(n // 4, 2)
def rate(a, b): return (c[b] - c[a]) / (t[b] - t[a]) * 5.0
first, last = rate(0, q), rate(n - 1 - q, n - 1)
print(f"{sys.argv[2]}: {sys.argv[3]} h at {sys.argv[4]}x, {n} samples; CPU per 5 s wall: first quarter {first:.3f} s, "
      f"last quarter {last:.3f} s (x{last / first:.2f}); RSS at the end of the first quarter {m[q] / 1024:.1f} MB, "
      f"at the end {m[-1] / 1024:.1f} MB (+{(m[-1] - m[q]) / 1024:.1f} MB)")
PY
