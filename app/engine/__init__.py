"""The calibration engine: the pipeline's stages (request, prepare, screen, fit, verify,
describe; :mod:`handeye.app.engine.calibrate` holds the stage map), the closed-form
baselines and the discrepancy workflow.
"""
