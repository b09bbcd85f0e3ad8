"""Which poses to measure and what they determine: identifiability (singular values of the Jacobian),
the Cramer-Rao bound, D-optimal planning, and the poses and the gate that make the robot's own
errors identifiable.
"""
