"""Recording I/O without rclpy.

``mcap`` (generic MCAP: writer, tolerant reader, :class:`~suds_ros.io.mcap.BagInfo`),
``recording_bag`` (the recording contract: topics, metadata keys, reader and writer),
``stamps`` (float ↔ ns, ROS stamps, quaternion yaw), ``cdr`` (CDR codec), ``msgdefs`` (schemas).
"""
