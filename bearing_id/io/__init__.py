"""Input/output at the edges: ROS message conversions (:mod:`.messages`) and rosbag2 bags (:mod:`.bags`).

Nothing is imported here, so ``import bearing_id.io`` needs neither rclpy nor rosbags.
"""
