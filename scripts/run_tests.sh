#!/usr/bin/env bash
# Run the test suite in the suds_ros venv: scripts/run_tests.sh [pytest args...]
#
# Without arguments the suite runs as two pytest processes side by side (one per core): the
# CPU-bound diagnosis tests in one, everything else (the ROS end-to-end tests among them) in the
# other; SUDS_TEST_JOBS=1 runs it as one process.  Tests marked `slow` (the long cross-checks on
# the public bags, multi-effect and lab diagnoses, the Γ targets) run only with SUDS_TEST_FULL=1.
# With arguments, one pytest gets them (and selects what they say).
# Fails when pytest collects no test (exit 5) as well as on any failure.
set -euo pipefail
ROOT=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd -P)
cd "$ROOT"
# shellcheck source=env.sh
source "$ROOT/scripts/env.sh"
export ROS_LOG_DIR
ROS_LOG_DIR=$(mktemp -d "${TMPDIR:-/tmp}/suds_ros_test_logs.XXXXXX")
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
# one BLAS thread per process: the two pytest processes and the nodes they start share the cores
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1

tmp=$(mktemp -d "${TMPDIR:-/tmp}/suds_ros_pytest.XXXXXX")
trap 'rm -rf "$tmp"' EXIT

summary_of() {
  grep -E '^(=+ )?[0-9]+ (passed|failed|error|skipped|deselected)|no tests ran' "$1" | tail -n 1 || true
}

# one pytest, output to the terminal and to $1; returns pytest's exit code
run_one() {
  local log=$1
  shift
  set +e
  python -m pytest -q "$@" 2>&1 | tee "$log"
  local rc=${PIPESTATUS[0]}
  set -e
  return "$rc"
}

jobs=${SUDS_TEST_JOBS:-2}
if [ "$#" -gt 0 ] || [ "$jobs" -le 1 ]; then
  rc=0
  run_one "$tmp/all.log" "$@" || rc=$?
  summary=$(summary_of "$tmp/all.log")
  echo "run_tests: ${summary:-no pytest summary line} (pytest exit $rc)"
  if [ "$rc" -eq 5 ]; then
    echo "run_tests: ERROR: no tests were collected" >&2
    exit 1
  fi
  exit "$rc"
fi

# the whole suite in two parts, side by side; each part's output is printed when it ends
marks=(-m "not slow")
what="without the slow cross-checks (SUDS_TEST_FULL=1 runs them too)"
if [ "${SUDS_TEST_FULL:-0}" = 1 ]; then
  marks=()
  what="every test"
fi
# the parts are chosen in test/conftest.py (SUDS_TEST_PART): the diagnosis tests / the rest
echo "run_tests: $what, as two pytest processes: the diagnosis tests and the rest"
common=(-q -p no:cacheprovider --durations=15 "${marks[@]}" test)
set +e
SUDS_TEST_PART=heavy python -m pytest "${common[@]}" >"$tmp/heavy.log" 2>&1 &
pid_heavy=$!
SUDS_TEST_PART=rest python -m pytest "${common[@]}" >"$tmp/rest.log" 2>&1 &
pid_rest=$!
wait "$pid_rest"
rc_rest=$?
echo "===== part 1 of 2: all but the diagnosis tests (pytest exit $rc_rest) ====="
cat "$tmp/rest.log"
wait "$pid_heavy"
rc_heavy=$?
echo "===== part 2 of 2: the diagnosis tests (pytest exit $rc_heavy) ====="
cat "$tmp/heavy.log"
set -e
s_rest=$(summary_of "$tmp/rest.log")
s_heavy=$(summary_of "$tmp/heavy.log")
echo "run_tests: part 1: ${s_rest:-no pytest summary line} (pytest exit $rc_rest)"
echo "run_tests: part 2: ${s_heavy:-no pytest summary line} (pytest exit $rc_heavy)"
if [ "$rc_rest" -eq 5 ] || [ "$rc_heavy" -eq 5 ]; then
  echo "run_tests: ERROR: a part collected no tests" >&2
  exit 1
fi
if [ "$rc_rest" -ne 0 ] || [ "$rc_heavy" -ne 0 ]; then
  exit 1
fi
exit 0
