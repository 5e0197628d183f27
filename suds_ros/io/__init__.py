"""Recording I/O without rclpy.

``mcap`` (generic MCAP: writer, readers, :class:`~suds_ros.io.mcap.BagInfo`), ``mcap_scan`` (the
tolerant reader of truncated or damaged files, streamed) and ``mcap_records`` (the ``mcap``
package's record parsers, bounded to each record),
``recording_bag`` (the recording contract: topics, metadata keys, reader and writer),
``stamps`` (float ↔ ns, ROS stamps, quaternion yaw), ``cdr`` (CDR through rosbags, two fast
decoders), ``msgdefs`` (schemas).
"""
