"""Launch the suds pipeline in a ROS 2 install: simulator, estimator, predictor, recorder.

    ros2 launch suds_ros suds_pipeline.launch.py system:=swimmer9 output:=/tmp/run.mcap

Each node loads ``share/suds_ros/config/<node>.yaml`` first, then the launch
arguments.  The recorder starts only when ``output`` is given.  Without the
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
    args = [
        DeclareLaunchArgument("system", default_value="purcell3", description="system id"),
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
            "seed": ParameterValue(LaunchConfiguration("seed"), value_type=int),
            "real_time_factor": ParameterValue(LaunchConfiguration("realtime_factor"),
                                              value_type=float),
        }),
        node("estimator", {"system": system}),
        node("predictor", {"system": system}),
        Node(package="suds_ros", executable="recorder", name="recorder", output="screen",
             condition=IfCondition(PythonExpression(["'", output, "' != ''"])),
             parameters=[os.path.join(config, "recorder.yaml"), {
                 "output": output, "system": system,
                 "actuated": LaunchConfiguration("actuated"),
                 "passive": LaunchConfiguration("passive")}]),
    ])
