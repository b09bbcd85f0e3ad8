"""Using a calibration: the text a robot, ROS 2 or URDF takes (formats), the saved file,
the point cloud and the validation of a scan (commands).
"""
