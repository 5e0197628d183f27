# Source me (bash/zsh): `source scripts/env.sh` -- environment for the suds_ros venv.
# Sets PATH, PYTHONPATH (the checkout), AMENT_PREFIX_PATH (the venv prefix holds share/ament_index) and a
# default ROS_LOG_DIR under /tmp; keeps any ROS_LOG_DIR / ROS_DOMAIN_ID already set.
_suds_root=$(cd -- "$(dirname -- "${BASH_SOURCE[0]:-$0}")/.." && pwd -P)
_suds_venv="$_suds_root/.venv"
if [ ! -x "$_suds_venv/bin/python" ]; then
  echo "env.sh: $_suds_venv does not exist; run scripts/setup_env.sh first" >&2
else
  export VIRTUAL_ENV="$_suds_venv"
  case ":$PATH:" in *":$_suds_venv/bin:"*) ;; *) export PATH="$_suds_venv/bin:$PATH" ;; esac
  case ":${AMENT_PREFIX_PATH:-}:" in
    *":$_suds_venv:"*) ;;
    *) export AMENT_PREFIX_PATH="$_suds_venv${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}" ;;
  esac
  # the checkout shadows the copy pip installed, so edits take effect without reinstalling
  case ":${PYTHONPATH:-}:" in
    *":$_suds_root:"*) ;;
    *) export PYTHONPATH="$_suds_root${PYTHONPATH:+:$PYTHONPATH}" ;;
  esac
  export ROS_LOG_DIR="${ROS_LOG_DIR:-/tmp/suds_ros_logs-$(id -u)}"
  mkdir -p "$ROS_LOG_DIR"
fi
unset _suds_root _suds_venv
