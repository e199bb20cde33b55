"""AnyScale decision side: pure algorithms (no ROS import) and thin rospy wrappers."""
