"""Presentation: the typed results and their one protocol, strict JSON, the text reports,
the figures and the notebooks' interactive panels.
"""
