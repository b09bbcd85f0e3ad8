"""The calibration as least squares and its estimators: the residual with exact derivatives, IPOPT's
problem (a CasADi graph or callbacks), the whole cell with positioner axes, the closed-form start,
the global minimum, the classic linear methods, and the extended model with the catalogue's effects
and its score tests.
"""
