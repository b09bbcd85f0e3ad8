"""Profile and sphere geometry: circle fits to a laser profile, what its arc says about the sphere
centre, profile cleaning, the least-squares sphere through a point cloud, and profiles into the
robot base with each point's uncertainty.
"""
