"""Tools around the engine: benchmarks, sweeps over studies and the study registry.
"""
