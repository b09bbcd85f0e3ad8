"""handeye's model: the kinematic chain, derived once symbolically, and the datasets.

Submodules: :mod:`handeye.model.chain.symbolic` (the one source), :mod:`handeye.model.chain.codegen` (numpy/CasADi
functions generated from it), :mod:`handeye.model.chain.pose`, :mod:`handeye.model.common.rotation`,
:mod:`handeye.model.chain.testfunction`, :mod:`handeye.model.fit.calibration`, :mod:`handeye.model.datasets.dataset`,
:mod:`handeye.model.design.identifiability`.

Rooms (subpackages by concern; tests/test_layers.py holds which room may import which): ``chain``,
``common``, ``compiled``, ``datasets``, ``design``, ``effects``, ``fit``, ``geometry``, ``readers``,
``robot``, ``simulation``.
"""
