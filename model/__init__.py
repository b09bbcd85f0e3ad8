"""handeye's model: the kinematic chain, derived once symbolically, and the datasets.

Submodules: :mod:`handeye.model.symbolic` (the one source), :mod:`handeye.model.codegen` (numpy/CasADi
functions generated from it), :mod:`handeye.model.pose`, :mod:`handeye.model.rotation`,
:mod:`handeye.model.testfunction`, :mod:`handeye.model.calibration`, :mod:`handeye.model.dataset`,
:mod:`handeye.model.identifiability`.
"""
