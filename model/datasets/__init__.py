"""Datasets as input: a folder of measurements.csv and setup.toml (and scans without a sphere) read
into samples, each row checked against its own profile, and the observations a calibration model is
built from (which residual, which weights).
"""
