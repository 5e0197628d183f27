"""Numerical core: physics, phase estimation, identification, diagnosis (no rclpy)."""
