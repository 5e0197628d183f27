"""ros/params.py: parameters generated from nested configs, checked by the config, applied after the set.

* the declared defaults, descriptions and ranges are the core configs' (a changed core default
  is the node's new default, with nothing copied into the node);
* a runtime set is checked by building the candidate config: a refusal names the field, what
  was expected and what was received;
* the config is applied in the post-set callback, so only after the set succeeded (a later
  on-set callback may still refuse it).
"""

from __future__ import annotations

from dataclasses import dataclass, fields, make_dataclass

import pytest

from suds_ros.core.config import check_settings, setting

pytestmark = pytest.mark.ros


@dataclass(frozen=True)
class Core:
    """A core config: its metadata is the one source."""

    gain: float = setting(0.5, "a gain, 1/s", gt=0.0, le=1.0, read_only=False)
    order: int = setting(3, "an order", ge=0, le=64)

    def __post_init__(self) -> None:
        check_settings(self)


@dataclass(frozen=True)
class FasterCore(Core):
    """The same core config after someone changed its defaults."""

    gain: float = setting(0.8, "a gain, 1/s", gt=0.0, le=1.0, read_only=False)
    order: int = setting(5, "an order", ge=0, le=64)


def node_config(core: type) -> type:
    """A node config holding ``core`` (flat names) and a field of its own."""
    return make_dataclass("NodeConfig", [
        ("core_settings", core, setting(default_factory=core, description="the core's",
                                        parameters={"flatten": True})),
        ("label", str, setting("x", "a label")),
    ], frozen=True, namespace={"__post_init__": check_settings})


def plain_node(context, name="toy", **overrides):
    from rclpy.node import Node
    from rclpy.parameter import Parameter

    return Node(name, context=context, parameter_overrides=[Parameter(k, value=v) for k, v in overrides.items()])


def test_declared_defaults_and_descriptors_come_from_the_core_config(ros_context):
    from suds_ros.ros.params import config_from_parameters

    for core, (gain, order) in ((Core, (0.5, 3)), (FasterCore, (0.8, 5))):
        node = plain_node(ros_context)
        try:
            cfg = config_from_parameters(node, node_config(core))
            assert node.get_parameter("gain").value == gain and node.get_parameter("order").value == order
            assert cfg.core_settings == core()
            d = node.describe_parameter("gain")
            assert d.description == "a gain, 1/s" and not d.read_only
            assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == (0.0, 1.0)
            assert d.additional_constraints == "a number in (0, 1]"
            assert node.describe_parameter("order").read_only
        finally:
            node.destroy_node()


def test_a_bad_start_value_stops_with_the_configs_reason(ros_context):
    from suds_ros.core.errors import OUT_OF_RANGE, SudsConfigError
    from suds_ros.ros.params import config_from_parameters

    node = plain_node(ros_context, gain=0.0)  # inside the descriptor's [0, 1], outside the config's (0, 1]
    try:
        with pytest.raises(SudsConfigError, match=r"`gain`: expected a number in \(0, 1\], got 0\.0") as info:
            config_from_parameters(node, node_config(Core))
        assert info.value.code == OUT_OF_RANGE
    finally:
        node.destroy_node()


def test_runtime_set_is_checked_on_set_and_applied_post_set(ros_context):
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.parameter import Parameter

    from suds_ros.ros.params import config_from_parameters, watch_parameters

    node = plain_node(ros_context)
    try:
        # registered first, so rclpy runs it after the config's check: it can refuse an accepted value
        node.add_on_set_parameters_callback(lambda params: SetParametersResult(
            successful=all(p.value != 0.25 for p in params), reason="vetoed"))
        state = {"config": config_from_parameters(node, node_config(Core))}
        applied = []

        def apply(new):
            applied.append((new, node.get_parameter("gain").value))  # the value is already stored
            state["config"] = new

        watch_parameters(node, lambda: state["config"], apply)
        before = state["config"]

        res = node.set_parameters([Parameter("gain", value=0.0)])[0]
        assert not res.successful and res.reason == "`gain`: expected a number in (0, 1], got 0.0"
        res = node.set_parameters([Parameter("gain", value=0.25)])[0]  # the config accepts, the veto refuses
        assert not res.successful and res.reason == "vetoed"
        assert applied == [] and state["config"] is before and node.get_parameter("gain").value == 0.5

        res = node.set_parameters([Parameter("gain", value=0.75)])[0]
        assert res.successful and len(applied) == 1
        new, stored = applied[0]
        assert new.core_settings.gain == 0.75 and stored == 0.75 and new.label == "x"
        assert state["config"].core_settings == Core(gain=0.75)

        res = node.set_parameters([Parameter("order", value=4)])[0]
        assert not res.successful and "read-only" in res.reason and len(applied) == 1
    finally:
        node.destroy_node()


def test_estimator_parameters_are_the_core_configs(ros_context):
    """Every estimator parameter's default is the default node config's value (nested ones included)."""
    from rclpy.exceptions import ParameterUninitializedException

    from suds_ros.core.ident.online import OnlineConfig
    from suds_ros.core.ident.sysid import SudsConfig
    from suds_ros.ros.estimator_node import EstimatorNode, EstimatorNodeConfig
    from suds_ros.ros.params import layout

    node = EstimatorNode(context=ros_context)
    try:
        default = EstimatorNodeConfig()
        for spec in layout(EstimatorNodeConfig).specs:
            value = default
            for attr in spec.path:
                value = getattr(value, attr)
            try:
                declared = node.get_parameter(spec.name).value
            except ParameterUninitializedException:  # an empty array is declared by type only
                declared = []
            assert (tuple(declared) if spec.is_array else declared) == value, spec.name
        # the estimator's own default (6), not SudsConfig's class default (3): taken from the default instance
        assert node.get_parameter("linear_order").value == OnlineConfig().suds.linear_order == 6
        assert node.get_parameter("chunk").value == OnlineConfig().chunk
        ridge = {f.name: f for f in fields(SudsConfig)}["ridge"]
        assert node.describe_parameter("ridge").description == ridge.metadata["description"]
        assert not node.describe_parameter("pose_stall").read_only and node.describe_parameter("chunk").read_only
        assert not node.has_parameter("alternatives") and not node.has_parameter("suds.ridge")
    finally:
        node.destroy_node()


def test_estimator_runtime_set_reaches_the_session_after_the_set(ros_context):
    from rclpy.parameter import Parameter

    from suds_ros.ros.estimator_node import EstimatorNode

    node = EstimatorNode(context=ros_context, parameter_overrides=[Parameter("system", value="purcell3")])
    try:
        res = node.set_parameters([Parameter("pose_stall", value=0.001)])[0]
        assert not res.successful and "pose_stall" in res.reason
        assert node.session.config.pose_stall == 60.0
        res = node.set_parameters([Parameter("pose_stall", value=5.0), Parameter("idle_flush", value=0.5)])[0]
        assert res.successful
        assert node.session.config is node.config is node.node_config.session
        assert (node.config.pose_stall, node.config.idle_flush) == (5.0, 0.5)
    finally:
        node.destroy_node()


def test_monitor_parameters_are_the_core_configs(ros_context):
    from suds_ros.core.diagnosis.monitor import MonitorConfig
    from suds_ros.ros.monitor_node import MonitorNode

    node = MonitorNode(context=ros_context)
    try:
        core = MonitorConfig()
        for name in ("rate", "warn", "error", "persist_cycles", "window_cycles", "update_every"):
            assert node.get_parameter(name).value == getattr(core, name), name
        assert node.get_parameter("gait_hz").value is None  # unset: the model's
        assert node.monitor.config == core  # purcell3: gait 1 Hz
        assert "(unset: the model's gait_hz)" in node.describe_parameter("gait_hz").description
    finally:
        node.close()
        node.destroy_node()


def test_simulator_refuses_bad_effects_at_runtime_naming_the_field(ros_context):
    from rclpy.parameter import Parameter

    from suds_ros.ros.simulator_node import SimulatorNode

    node = SimulatorNode(context=ros_context, parameter_overrides=[Parameter("real_time_factor", value=0.0)])
    try:
        res = node.set_parameters([Parameter("effects", value="[not json")])[0]
        assert not res.successful and res.reason.startswith("`effects`: expected a JSON list")
        assert node.config.effects == "" and node._pending_effects is None
    finally:
        node.destroy_node()
