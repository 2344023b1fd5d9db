"""Pure algorithms: numpy in, numpy and dataclasses out.  Nothing here imports rclpy."""
