"""The installed executables: name → module whose ``main()`` runs it.

The one table of them.  ``setup.py`` reads this file with :func:`runpy.run_path`
(without importing the package), so it must stay plain Python with no imports;
:mod:`suds_ros.ros.pipeline` takes its node modules from here.
"""

#: executable name -> module holding ``main()``
EXECUTABLES = {
    "simulator": "suds_ros.ros.simulator_node",
    "estimator": "suds_ros.ros.estimator_node",
    "predictor": "suds_ros.ros.predictor_node",
    "recorder": "suds_ros.ros.recorder_node",
    "player": "suds_ros.ros.player_node",
    "monitor": "suds_ros.ros.monitor_node",
    "optimizer": "suds_ros.ros.optimizer_node",
    "foxglove_bridge": "suds_ros.ros.foxglove_node",
    "pipeline": "suds_ros.ros.pipeline",
    "suds": "suds_ros.cli.main",
}
