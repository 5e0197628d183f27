"""Thin ROS 2 adapters around the core; the only package that imports rclpy."""
