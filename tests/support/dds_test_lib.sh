# Sourced by the DDS test scripts (tests/dds/*.sh, tests/interop/*.sh): the
# set-up they share. Loopback only: the built-in magnav_loopback profile.
#   dds_test_setup       MAGNAV_DOMAIN_ID = a domain of the test's own
#                        (dds_claim_domain), no profile, participant or ROS 2
#                        naming from the caller's environment; WORK, a
#                        temporary directory, and `pids`, processes killed (-9)
#                        at exit, when WORK is removed
#   dds_claim_domain     MAGNAV_DOMAIN_ID = an even domain in [10, 228] whose
#                        lock file in $TMPDIR/magnav-test-domains this shell
#                        can flock (held while the shell or a child holds the
#                        descriptor; the odd domain after it comes with it):
#                        the same claim as the C++ tests' TestDomainId(), so
#                        tests run side by side never share a domain
#   col FILE NAME        a CSV column by header name, one value per row
#   valid_fixes FILE     the valid fixes of a dipole_fix CSV as "t x y z", sorted
#   fail MESSAGE...      prints FAIL (with the run number if $run is set), the
#                        last lines of every log in WORK, and exits 1
dds_claim_domain() {
  local dir="${TMPDIR:-/tmp}/magnav-test-domains" i d fd
  mkdir -p "$dir"
  for i in $(seq 0 109); do
    d=$(( 10 + 2 * (($$ + BASHPID + i) % 110) ))
    exec {fd}>>"$dir/$d.lock" || continue
    if flock -n "$fd"; then
      export MAGNAV_DOMAIN_ID=$d
      return 0
    fi
    exec {fd}>&-
  done
  echo "no free DDS test domain: every lock in $dir is held" >&2
  return 1
}

dds_test_setup() {
  dds_claim_domain || exit 1
  unset MAGNAV_DDS_PROFILES MAGNAV_DDS_PARTICIPANT MAGNAV_ROS2_NAMES
  WORK=$(mktemp -d)
  pids=()
  trap dds_test_cleanup EXIT
}

dds_test_cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  rm -rf "$WORK"
}

col() {
  awk -F, -v name="$2" '/^#/ { next } !h { for (i = 1; i <= NF; i++) if ($i == name) c = i; h = 1; next }
                        { print $c }' "$1"
}

valid_fixes() {
  awk -F, '/^#/ { next } !h { for (i = 1; i <= NF; i++) c[$i] = i; h = 1; next }
           $c["valid"] == 1 { print $c["t"], $c["dipole_x"], $c["dipole_y"], $c["dipole_z"] }' "$1" | sort
}

fail() {
  echo "FAIL${run:+ (run $run)}: $*"
  for f in "$WORK"/*.log; do
    [ -f "$f" ] || continue
    echo "== $f"
    tail -"${FAIL_LOG_LINES:-8}" "$f"
  done
  exit 1
}
