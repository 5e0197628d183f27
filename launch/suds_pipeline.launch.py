"""Launch the suds pipeline in a ROS 2 install: simulator, estimator, predictor, recorder.

    ros2 launch suds_ros suds_pipeline.launch.py system:=swimmer9 output:=/tmp/run.mcap
    ros2 launch suds_ros suds_pipeline.launch.py namespace:=/robot1 model:=/abs/snake5.yaml \
        rate:=50.0 output:=/tmp/run.mcap actuated:=joint_1,joint_2 passive:=joint_3,joint_4

The arguments are the ``pipeline`` supervisor's options (``suds_ros/ros/pipeline.py``;
test/ros/test_launch_file.py keeps the two in step): ``namespace``, ``system`` or
``model`` (a robot model file), ``cycles``, ``rate``, ``seed``, ``realtime_factor``,
``output``, ``overwrite``, ``foxglove`` (a WebSocket port for the Foxglove app, 0: off),
``optimize`` (an objective: starts the ``optimizer`` node, which commands gaits to the simulator)
and ``optimize_budget``;
plus ``actuated`` and ``passive``, the joint roles the
recorder writes into the bag's metadata (the supervisor reads them from the system).
Each node loads ``share/suds_ros/config/<node>.yaml`` first, then the launch
arguments, and runs in ``namespace`` (its topics are ``<namespace>/suds/...``).  The
recorder starts only when ``output`` is given.  With ``model`` the simulator simulates
that file and the estimator takes the joint roles from the simulator's ``suds/system``;
``system`` is then only the id the recorder writes.  Without the ``launch`` package
(e.g. a pip venv) use the ``pipeline`` executable instead.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue

#: name -> (default, description); the names are the pipeline supervisor's option names
ARGUMENTS = {
    "namespace": ("", "ROS namespace of every node, e.g. /robot1"),
    "system": ("purcell3", "system id"),
    "model": ("", "robot model file (suds-robot/1) to simulate instead of `system`"),
    "cycles": ("0", "gait cycles the simulator runs (0: forever)"),
    "rate": ("100.0", "simulator sample rate, Hz"),
    "seed": ("0", "simulator seed"),
    "realtime_factor": ("1.0", "simulated seconds per wall-clock second"),
    "output": ("", "bag to record (.mcap); empty: no recorder"),
    "overwrite": ("false", "let the recorder replace `output`"),
    "foxglove": ("0", "serve the topics to the Foxglove app on this WebSocket port (0: off)"),
    "optimize": ("", "optimise the gait live for this objective (speed or turn; empty: off)"),
    "optimize_budget": ("200", "gait cycles the optimizer may ask for"),
    "actuated": ("joint_1", "recorder metadata: actuated joints"),
    "passive": ("joint_2", "recorder metadata: passive joints"),
}


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(get_package_share_directory("suds_ros"), "config")
    arg = {name: LaunchConfiguration(name) for name in ARGUMENTS}
    # with a model file the estimator takes the roles from suds/system (its `system` left empty)
    estimator_system = PythonExpression(["'' if '", arg["model"], "' else '", arg["system"], "'"])

    def node(name: str, params: dict, **kwargs) -> Node:
        return Node(package="suds_ros", executable=name, name=name, output="screen",
                    namespace=arg["namespace"],
                    parameters=[os.path.join(config, f"{name}.yaml"), params], **kwargs)

    return LaunchDescription([
        *(DeclareLaunchArgument(name, default_value=default, description=text)
          for name, (default, text) in ARGUMENTS.items()),
        node("simulator", {
            "system": arg["system"],
            "model_file": ParameterValue(arg["model"], value_type=str),
            "cycles": ParameterValue(arg["cycles"], value_type=int),
            "rate": ParameterValue(arg["rate"], value_type=float),
            "seed": ParameterValue(arg["seed"], value_type=int),
            "real_time_factor": ParameterValue(arg["realtime_factor"], value_type=float),
            # start the stream once the other nodes listen (estimator, predictor, recorder, bridge)
            "wait_for_subscribers": ParameterValue(PythonExpression(
                ["2 + int('", arg["output"], "' != '') + int(int('", arg["foxglove"], "') != 0) + int('",
                 arg["optimize"], "' != '')"]),
                value_type=int),
        }),
        node("estimator", {"system": ParameterValue(estimator_system, value_type=str)}),
        node("predictor", {"system": arg["system"]}),
        node("recorder", {
            "output": arg["output"], "system": arg["system"],
            "overwrite": ParameterValue(arg["overwrite"], value_type=bool),
            "actuated": arg["actuated"], "passive": arg["passive"]},
            condition=IfCondition(PythonExpression(["'", arg["output"], "' != ''"]))),
        node("foxglove_bridge", {"port": ParameterValue(arg["foxglove"], value_type=int)},
             condition=IfCondition(PythonExpression(["int('", arg["foxglove"], "') != 0"]))),
        node("optimizer", {
            "system": arg["system"], "model_file": ParameterValue(arg["model"], value_type=str),
            "objective": arg["optimize"], "budget_cycles": ParameterValue(arg["optimize_budget"], value_type=int)},
            condition=IfCondition(PythonExpression(["'", arg["optimize"], "' != ''"]))),
    ])
