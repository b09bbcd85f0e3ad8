"""Compiled code: the C drivers (fast_lm.c, fast_starts.c) around CasADi-generated C, compiled once and
cached, and the fast paths that call them.
"""
