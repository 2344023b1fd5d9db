"""rclpy nodes (one per file), the shared node base and message <-> numpy conversions."""
