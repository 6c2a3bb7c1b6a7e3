#!/usr/bin/env bash
# More than one host, for real but inside this machine: three network
# namespaces made here ("hosts" A, B, C: a bridge in A, a veth pair to each of
# B and C, addresses 10.77.0.1-3 that exist only inside them; nothing is sent
# anywhere else), a Fast DDS discovery server in A, and the field profile
# (config/magnav_field.xml: UDP only, discovery through the server):
#   A: magnav replay of a simulated pass      B: magnav-inverter      C: magnav record
# Passes when every sample gets its fix at C and the valid fixes equal the
# offline `magnav invert` of the same pass; then checks that without the
# server nothing is discovered. Skips (exit 77) where namespaces cannot be
# made (not root, or no iproute2).
# Usage: multihost_test.sh BIN_DIR SOURCE_DIR
set -euo pipefail
BIN=$1
SRC=$2
SKIP=77
if [ "$(id -u)" -ne 0 ] || ! command -v ip >/dev/null; then
  echo "SKIP: network namespaces need root and iproute2 (ip)"; exit $SKIP
fi
ID=$$
A=magnavA$ID B=magnavB$ID C=magnavC$ID
WORK=$(mktemp -d)
cleanup() {
  for n in "$A" "$B" "$C"; do
    ip netns pids "$n" 2>/dev/null | xargs -r kill -9 2>/dev/null || true
    ip netns del "$n" 2>/dev/null || true
  done
  rm -rf "$WORK"
}
trap cleanup EXIT
if ! ip netns add "$A" 2>/dev/null; then echo "SKIP: cannot create a network namespace here"; exit $SKIP; fi
ip netns add "$B"; ip netns add "$C"
ip -n "$A" link add br0 type bridge
i=2
for n in "$B" "$C"; do
  ip link add "v$i$ID" netns "$A" type veth peer name eth0 netns "$n"
  ip -n "$A" link set "v$i$ID" master br0
  ip -n "$A" link set "v$i$ID" up
  ip -n "$n" addr add "10.77.0.$i/24" dev eth0
  ip -n "$n" link set eth0 up
  ip -n "$n" link set lo up
  i=$((i + 1))
done
ip -n "$A" addr add 10.77.0.1/24 dev br0
ip -n "$A" link set br0 up
ip -n "$A" link set lo up

export MAGNAV_DDS_PROFILES="$SRC/config/magnav_field.xml" MAGNAV_DDS_PARTICIPANT=magnav_udp MAGNAV_DOMAIN_ID=7
B0=2e-05,1e-06,4.5e-05
"$BIN/magnav" simulate --noise squid --b0 "$B0" --output "$WORK/pass.csv" --truth "$WORK/truth.csv" >/dev/null
"$BIN/magnav" invert --input "$WORK/pass.csv" --method ted-egt --output "$WORK/offline.csv" >/dev/null
want_valid=$(awk -F, '/^#/ || $1 == "t" { if ($1 == "t") for (i = 1; i <= NF; i++) c[$i] = i; next } $c["valid"] == 1 { n++ } END { print n + 0 }' "$WORK/offline.csv")

run() {  # run WITH_SERVER(1|0) -> prints "received valid"
  local with_server=$1 server_pid=""
  rm -f "$WORK/fixes.csv"
  export ROS_DISCOVERY_SERVER=10.77.0.1:11811
  if [ "$with_server" = 1 ]; then
    ip netns exec "$A" fastdds discovery -i 0 -l 10.77.0.1 -p 11811 >"$WORK/server.log" 2>&1 &
    server_pid=$!
    sleep 1
  fi
  ip netns exec "$B" "$BIN/magnav-inverter" --b0 "$B0" --stats-period 0 >"$WORK/inverter.log" 2>&1 &
  local inv=$!
  ip netns exec "$C" "$BIN/magnav" record --topic dipole_fix --count 2001 --duration 60 \
      --output "$WORK/fixes.csv" >"$WORK/record.log" 2>&1 &
  local rec=$!
  sleep 1
  if ! ip netns exec "$A" "$BIN/magnav" replay --input "$WORK/pass.csv" --speed 0 --wait-readers 1 --wait 8 \
      >"$WORK/replay.log" 2>&1; then
    kill -TERM "$rec" 2>/dev/null || true
  fi
  wait "$rec" || true
  kill -TERM "$inv" 2>/dev/null || true; wait "$inv" 2>/dev/null || true
  if [ -n "$server_pid" ]; then
    # `fastdds discovery` is a wrapper that starts the server as a child: end everything in A.
    ip netns pids "$A" | xargs -r kill -TERM 2>/dev/null || true
    wait "$server_pid" 2>/dev/null || true
    sleep 0.5
    ip netns pids "$A" | xargs -r kill -9 2>/dev/null || true
  fi
  awk -F, '/^#/ { next } $1 == "t" { for (i = 1; i <= NF; i++) c[$i] = i; next } { n++; if ($c["valid"] == 1) v++ }
           END { print n + 0, v + 0 }' "$WORK/fixes.csv" 2>/dev/null || echo "0 0"
}

read -r got valid < <(run 1)
echo "with the discovery server: $got of 2001 samples got a fix at C, $valid valid (offline: $want_valid)"
if [ "$got" != 2001 ] || [ "$valid" != "$want_valid" ]; then
  echo "FAIL"; cat "$WORK/replay.log" "$WORK/record.log" "$WORK/inverter.log"; exit 1
fi
read -r got0 valid0 < <(run 0)
echo "without it: $got0 fixes ($(tail -1 "$WORK/replay.log"))"
if [ "$got0" != 0 ]; then echo "FAIL: participants found each other without the server"; exit 1; fi
echo "1 passed, 0 failed"
