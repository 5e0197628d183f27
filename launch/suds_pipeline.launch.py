"""Launch the suds pipeline in a ROS 2 install: simulator, estimator, predictor, recorder.

    ros2 launch suds_ros suds_pipeline.launch.py system:=swimmer9 output:=/tmp/run.mcap
    ros2 launch suds_ros suds_pipeline.launch.py model_file:=/abs/snake5.yaml system:=snake5 \
        output:=/tmp/run.mcap actuated:=joint_1,joint_2 passive:=joint_3,joint_4

Each node loads ``share/suds_ros/config/<node>.yaml`` first, then the launch
arguments.  The recorder starts only when ``output`` is given.  With ``model_file``
(a robot model file) the simulator simulates that file, the estimator takes the joint
roles from the simulator's ``/suds/system``; ``system`` is then only the id the
recorder writes (the file's ``name``): give it with the recorder's ``actuated`` and
``passive``, and a ``rate`` that is a whole number of samples per gait cycle.  Without the
``launch`` package (e.g. a pip venv) use the ``pipeline`` executable instead.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PythonExpression
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(get_package_share_directory("suds_ros"), "config")
    system = LaunchConfiguration("system")
    output = LaunchConfiguration("output")
    model_file = LaunchConfiguration("model_file")
    # with a model file the estimator takes the roles from /suds/system (its `system` left empty)
    estimator_system = PythonExpression(["'' if '", model_file, "' else '", system, "'"])
    args = [
        DeclareLaunchArgument("system", default_value="purcell3", description="system id"),
        DeclareLaunchArgument("model_file", default_value="",
                              description="robot model file (suds-robot/1) to simulate instead of `system`"),
        DeclareLaunchArgument("rate", default_value="100.0", description="simulator sample rate, Hz"),
        DeclareLaunchArgument("output", default_value="", description="bag to record (.mcap)"),
        DeclareLaunchArgument("seed", default_value="0", description="simulator seed"),
        DeclareLaunchArgument("realtime_factor", default_value="1.0",
                              description="simulated seconds per wall-clock second"),
        DeclareLaunchArgument("actuated", default_value="joint_1",
                              description="recorder metadata: actuated joints"),
        DeclareLaunchArgument("passive", default_value="joint_2",
                              description="recorder metadata: passive joints"),
    ]

    def node(name: str, params: dict) -> Node:
        return Node(package="suds_ros", executable=name, name=name, output="screen",
                    parameters=[os.path.join(config, f"{name}.yaml"), params])

    return LaunchDescription([
        *args,
        node("simulator", {
            "system": system,
            "model_file": ParameterValue(model_file, value_type=str),
            "rate": ParameterValue(LaunchConfiguration("rate"), value_type=float),
            "seed": ParameterValue(LaunchConfiguration("seed"), value_type=int),
            "real_time_factor": ParameterValue(LaunchConfiguration("realtime_factor"),
                                              value_type=float),
        }),
        node("estimator", {"system": ParameterValue(estimator_system, value_type=str)}),
        node("predictor", {"system": system}),
        Node(package="suds_ros", executable="recorder", name="recorder", output="screen",
             condition=IfCondition(PythonExpression(["'", output, "' != ''"])),
             parameters=[os.path.join(config, "recorder.yaml"), {
                 "output": output, "system": system,
                 "actuated": LaunchConfiguration("actuated"),
                 "passive": LaunchConfiguration("passive")}]),
    ])
