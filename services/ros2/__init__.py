"""roco's runs in ROS 2's formats: the message definitions of package ``roco_msgs``
(:mod:`services.ros2.messages`), a run exported as a rosbag2 MCAP folder (``roco export``) and
such a folder read back into roco's traffic record. Needs the ``ros2`` extra (rosbags, mcap,
mcap-ros2-support)."""
