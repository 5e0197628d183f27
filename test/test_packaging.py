"""The ament_python install contract, checked on a real install into a temporary venv.

``ros2 run suds_ros <exe>`` finds the first prefix in ``AMENT_PREFIX_PATH`` with
``share/ament_index/resource_index/packages/suds_ros`` and runs
``<prefix>/lib/suds_ros/<exe>``.  A pip install must produce that layout, and
the launcher must use the interpreter of the environment it was installed into.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from suds_ros.executables import EXECUTABLES

ROOT = Path(__file__).resolve().parents[1]
IGNORE = shutil.ignore_patterns(".venv", ".git", "build", "*.egg-info", "__pycache__",
                                ".pytest_cache", "bags", "log", "install", "*.mcap")


def _source_copy(tmp: Path) -> Path:
    src = tmp / "src"
    shutil.copytree(ROOT, src, ignore=IGNORE)
    return src


@pytest.fixture(scope="module")
def venv_prefix(tmp_path_factory) -> Path:
    """A fresh venv (no pip) that sees this environment's packages, with suds_ros pip-installed."""
    pytest.importorskip("setuptools")
    tmp = tmp_path_factory.mktemp("pkg")
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", venv], check=True)
    site = Path(subprocess.check_output(
        [venv / "bin" / "python", "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        text=True).strip())
    outer = sysconfig.get_paths()["purelib"]  # addsitedir also runs its .pth files (ROS wheels)
    (site / "_outer_env.pth").write_text(f"import site; site.addsitedir({outer!r})\n")
    # as `<venv>/bin/pip install .` would; -I: never touch the outer environment's installs
    proc = subprocess.run(
        [venv / "bin" / "python", "-m", "pip", "install", "--quiet", "--no-deps", "-I",
         "--no-build-isolation", "--disable-pip-version-check", "--prefix", venv,
         _source_copy(tmp)],
        capture_output=True, text=True, timeout=120)
    if proc.returncode and "No module named 'wheel'" in proc.stderr + proc.stdout:
        pytest.skip("building a wheel needs the `wheel` package (run scripts/setup_env.sh)")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return venv


def ros2_run_path(exe: str, ament_prefix_path: str) -> Path:
    """Resolve ``ros2 run suds_ros <exe>`` the way ros2cli/ament_index do."""
    for prefix in ament_prefix_path.split(os.pathsep):
        if (Path(prefix) / "share/ament_index/resource_index/packages/suds_ros").is_file():
            return Path(prefix) / "lib" / "suds_ros" / exe
    raise LookupError(f"suds_ros is not in any prefix of {ament_prefix_path!r}")


def test_ament_index_and_package_xml(venv_prefix):
    assert (venv_prefix / "share/ament_index/resource_index/packages/suds_ros").is_file()
    root = ET.parse(venv_prefix / "share/suds_ros/package.xml").getroot()
    assert root.tag == "package" and root.get("format") == "3"
    assert root.findtext("name") == "suds_ros"
    assert root.findtext("export/build_type") == "ament_python"
    deps = {e.text for e in root.findall("exec_depend")}
    assert {"rclpy", "sensor_msgs", "geometry_msgs", "diagnostic_msgs", "rosgraph_msgs",
            "builtin_interfaces", "std_msgs", "python3-numpy", "python3-scipy",
            "python3-threadpoolctl"} <= deps


def test_shared_files_and_msg_defs_package_data(venv_prefix):
    share = venv_prefix / "share/suds_ros"
    assert (share / "launch/suds_pipeline.launch.py").is_file()
    assert sorted(p.name for p in (share / "config").glob("*.yaml"))
    assert (share / "foxglove/suds_layout.json").is_file()
    msgs = sorted(p.name for p in (share / "msg_defs").glob("*.msg"))
    assert "sensor_msgs__msg__JointState.msg" in msgs
    assert (share / "msg_defs/type_hashes.txt").is_file()
    site = next(venv_prefix.glob("lib/python3*/site-packages"))
    assert sorted(p.name for p in (site / "suds_ros/io/_msg_defs").glob("*.msg")) == msgs


@pytest.mark.parametrize("exe", sorted(EXECUTABLES))
def test_executable_resolves_and_runs_with_the_venv_python(venv_prefix, exe, tmp_path):
    if importlib.util.find_spec(EXECUTABLES[exe]) is None:
        pytest.skip(f"{EXECUTABLES[exe]} is not written yet")
    ament = os.pathsep.join([str(venv_prefix), sys.prefix])
    path = ros2_run_path(exe, ament)
    assert path == venv_prefix / "lib/suds_ros" / exe
    assert path.is_file() and os.access(path, os.X_OK)
    # PATH without any Python: the launcher must find <venv>/bin/python itself
    env = {"PATH": "/nonexistent", "HOME": str(tmp_path), "AMENT_PREFIX_PATH": ament,
           "ROS_LOG_DIR": str(tmp_path / "log")}
    # the test venv borrows this environment's ROS wheels: keep their library path
    for key in ("LD_LIBRARY_PATH", "_ROS_WHEELS_BOOTSTRAP_COMPLETE"):
        if key in os.environ:
            env[key] = os.environ[key]
    proc = subprocess.run([path, "--help"],
                          env=env, capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "usage" in proc.stdout.lower()


def test_console_scripts_in_bin(venv_prefix):
    for exe in EXECUTABLES:
        script = venv_prefix / "bin" / exe
        assert script.is_file(), exe
        assert script.read_text().splitlines()[0] == f"#!{venv_prefix / 'bin' / 'python'}"


def test_colcon_style_install_puts_console_scripts_in_lib(tmp_path):
    """colcon runs `setup.py install`: setup.cfg sends scripts to lib/suds_ros, no shell launchers."""
    src = _source_copy(tmp_path)
    prefix = tmp_path / "install"
    proc = subprocess.run(
        [sys.executable, "setup.py", "-q", "build", "--build-base", tmp_path / "build", "install",
         "--prefix", prefix, "--single-version-externally-managed", "--record", tmp_path / "rec"],
        cwd=src, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert not (src / "build" / "suds_ros_launchers").exists()
    for exe in EXECUTABLES:
        script = prefix / "lib/suds_ros" / exe
        assert os.access(script, os.X_OK), exe
        assert script.read_text().startswith("#!"), exe
        assert "suds_ros launcher" not in script.read_text()
    assert (prefix / "share/ament_index/resource_index/packages/suds_ros").is_file()
