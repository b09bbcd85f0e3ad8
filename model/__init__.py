"""handeye's model: the kinematic chain, derived once symbolically, and the datasets.

Submodules: :mod:`model.symbolic` (the one source), :mod:`model.codegen` (numpy/CasADi
functions generated from it), :mod:`model.pose`, :mod:`model.rotation`,
:mod:`model.testfunction`, :mod:`model.calibration`, :mod:`model.dataset`,
:mod:`model.identifiability`.
"""
