"""handeye's application layer: what the ``handeye`` command does, as Python.

:mod:`~handeye.app.api` (the public functions ``import handeye`` gives),
:mod:`~handeye.app.calibrate` (checks, screening, solve), :mod:`~handeye.app.robust`
(outlier tests, leave-one-out), :mod:`~handeye.app.classic` (closed-form baselines),
:mod:`~handeye.app.diagnose` (model discrepancy), :mod:`~handeye.app.results` (typed
results), :mod:`~handeye.app.report` (text and figures), :mod:`~handeye.app.bench`,
:mod:`~handeye.app.sweep` (parallel sweeps), :mod:`~handeye.app.cli` (the command line).
Uses :mod:`handeye.model` and :mod:`handeye.solvers`; never :mod:`handeye.studies` (but
the CLI's ``handeye study``, which imports it when run).
"""
