"""Simulation: the thesis's cell with a realistic sensor and sphere, every other mount, a robot with
joints and hidden offsets, and the motion strategies.
"""
