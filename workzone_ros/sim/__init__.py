"""Synthetic highway work-zone world: scenarios, sign art, camera renderer, LiDAR ray caster,
ground truth and the bag writer.  No rclpy import."""
