#!/usr/bin/env bash
# Create (or update) the development venv .venv with the ROS 2 Jazzy wheels and
# install suds_ros into it.  Idempotent: re-running only
# installs what is missing.  Exports nothing; see the message at the end.
set -euo pipefail

ROOT=$(cd -- "$(dirname -- "${BASH_SOURCE[0]}")/.." && pwd -P)
VENV="$ROOT/.venv"
PY=${PYTHON:-python3.11}

if [ ! -x "$VENV/bin/python" ]; then
  echo "setup_env: creating $VENV with $PY"
  "$PY" -m venv "$VENV"
fi
VPY="$VENV/bin/python"

# runtime: rclpy and the messages, numpy, scipy, threadpoolctl, mcap, rosbags (the CDR codec, io/cdr.py);
# tests and extras: mcap-ros2-support (a second CDR decoder), matplotlib, pytest, linters, foxglove-sdk,
# movement (the animal-tracking readers and writers: `suds import` of DeepLabCut .h5 / SLEAP / LightningPose
# needs it, and the import round-trip tests write their files with it; ~1.3 GB, about 80 s from the registry)
DEPS=("ros-jazzy-rclpy[fastrtps]" ros-jazzy-common-interfaces numpy scipy threadpoolctl mcap rosbags
      mcap-ros2-support matplotlib pytest flake8 pydocstyle foxglove-sdk movement)
# setuptools' bdist_wheel needs `wheel` before setuptools 70.1 (editable and --no-build-isolation builds)
BUILD=(wheel)

if ! "$VPY" -c 'import rclpy, sensor_msgs.msg, numpy, scipy, threadpoolctl, mcap, mcap_ros2, matplotlib, pytest, rosbags, wheel, flake8, pydocstyle, foxglove, movement' 2>/dev/null; then
  echo "setup_env: installing dependencies"
  "$VPY" -m pip install --quiet --disable-pip-version-check "${DEPS[@]}" "${BUILD[@]}"
fi

# A regular (non-editable) install: setuptools' editable wheels leave out
# data_files, i.e. the ament index entry, share/suds_ros and the launchers in
# .venv/lib/suds_ros/ that `ros2 run`-style lookups through
# AMENT_PREFIX_PATH=.venv need.  scripts/env.sh puts the checkout first on
# PYTHONPATH, so the code you edit is what runs; re-run this script after
# changing setup.py, package.xml, config/, launch/ or msg_defs/.
echo "setup_env: installing suds_ros into $VENV"
"$VPY" -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation \
  --force-reinstall "$ROOT"

for exe in simulator estimator predictor monitor optimizer recorder player foxglove_bridge pipeline suds; do
  if [ ! -x "$VENV/lib/suds_ros/$exe" ]; then
    echo "setup_env: ERROR: $VENV/lib/suds_ros/$exe was not installed" >&2
    exit 1
  fi
done

# Foxglove's MCAP/CDR readers (Node) for the third-party reader test, where Node is present
if command -v node >/dev/null 2>&1 && command -v npm >/dev/null 2>&1; then
  if [ ! -d "$ROOT/test/js/node_modules/@mcap/core" ]; then
    echo "setup_env: installing Foxglove readers for the tests (npm ci in test/js)"
    (cd "$ROOT/test/js" && npm ci --no-audit --no-fund --loglevel=error) \
      || echo "setup_env: WARNING: npm ci failed; the Foxglove reader tests will be skipped" >&2
  fi
else
  echo "setup_env: Node.js not found; the Foxglove reader tests will be skipped"
fi

cat <<MSG
setup_env: done.  To use the environment in a shell:
    source "$ROOT/scripts/env.sh"
(sets PATH, PYTHONPATH=$ROOT, AMENT_PREFIX_PATH=$VENV and a default ROS_LOG_DIR under /tmp)
MSG
