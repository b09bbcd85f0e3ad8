"""The kinematic chain, derived once: the one symbolic source (sympy), the numpy and CasADi functions
generated from it with their disk cache, the option names, poses and robot-brand conventions, the
mounts every cell reduces to, and the thesis's test function.
"""
