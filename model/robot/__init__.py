"""Robot kinematics and the robot's own errors: nominal models (joint angles to the flange pose the
controller reports) and the real arm's zero offsets, length errors and sag.
"""
