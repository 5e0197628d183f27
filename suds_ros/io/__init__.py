"""Recording I/O (MCAP, ROS 2 profile) without rclpy."""
