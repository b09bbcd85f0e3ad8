"""handeye's application layer: what the ``handeye`` command does, as Python.

:mod:`~handeye.app.public.api` (the public functions ``import handeye`` gives),
:mod:`~handeye.app.engine.calibrate` (checks, screening, solve), :mod:`~handeye.app.engine.robust`
(outlier tests, leave-one-out), :mod:`~handeye.app.engine.classic` (closed-form baselines),
:mod:`~handeye.app.engine.diagnose` (model discrepancy), :mod:`~handeye.app.present.results` (typed
results), :mod:`~handeye.app.present.report` (text and figures), :mod:`~handeye.app.tools.bench`,
:mod:`~handeye.app.tools.sweep` (parallel sweeps), :mod:`~handeye.app.command.cli` (the command line).
Uses :mod:`handeye.model` and :mod:`handeye.solvers`; never :mod:`handeye.studies` (but
the CLI's ``handeye study``, which imports it when run).

Rooms (subpackages by concern; tests/test_layers.py holds which room may import which): ``command``,
``common``, ``engine``, ``ingest``, ``outputs``, ``present``, ``public``, ``tools``.
"""
