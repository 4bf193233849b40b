# noqa: A005  (bearing_id.io is only ever imported by its full name; renaming it would change the public API)
"""
Input/output at the edges: ROS message conversions (:mod:`.messages`) and rosbag2 bags (:mod:`.bags`).

Nothing is imported here, so ``import bearing_id.io`` needs neither rclpy nor rosbags.
"""
