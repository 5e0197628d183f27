#!/usr/bin/env bash
# Run the test suite in the suds_ros venv: scripts/run_tests.sh [pytest args...]
# Fails when pytest collects no test (exit 5) as well as on any failure.
set -euo pipefail
ROOT=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd -P)
cd "$ROOT"
# shellcheck source=env.sh
source "$ROOT/scripts/env.sh"
export ROS_LOG_DIR
ROS_LOG_DIR=$(mktemp -d "${TMPDIR:-/tmp}/suds_ros_test_logs.XXXXXX")
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST

log=$(mktemp "${TMPDIR:-/tmp}/suds_ros_pytest.XXXXXX")
trap 'rm -f "$log"' EXIT
set +e
python -m pytest -q "$@" 2>&1 | tee "$log"
rc=${PIPESTATUS[0]}
set -e
summary=$(grep -E '^(=+ )?[0-9]+ (passed|failed|error|skipped|deselected)|no tests ran' "$log" | tail -n 1 || true)
echo "run_tests: ${summary:-no pytest summary line} (pytest exit $rc)"
if [ "$rc" -eq 5 ]; then
  echo "run_tests: ERROR: no tests were collected" >&2
  exit 1
fi
exit "$rc"
