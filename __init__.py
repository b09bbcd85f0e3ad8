"""handeye: a workbench for robot hand-eye calibration (laser-line sensor, precision sphere).

The public API (the ``handeye`` command's functions, with its options as keyword arguments)::

    import handeye
    data = handeye.load_dataset("thesis-sim")      # or a folder of your own
    r = handeye.calibrate(data)                    # a CalibrationResult
    r.sensor2flange, r.sensor_pose, r.std, r.converged
    r.to_dict()                                    # == handeye calibrate thesis-sim --json
    print(r.summary())                             # == its text report
    d = handeye.diagnose(data)                     # a DiagnosisResult
    handeye.simulate("my-sim", seed=1, effect=["sensor_scale=0.001"])
    handeye.plan(n=12)

Bad input raises :class:`InputError` (a ``ValueError``), naming file, row and column or the
option. The layers: :mod:`handeye.solvers` (knows nothing of robots) <- :mod:`handeye.model`
(the mathematics, derived once) <- :mod:`handeye.app` (calibrate, diagnose, reports, CLI) <-
:mod:`handeye.studies` (studies that assert their claims).
"""
from handeye.app.api import PlanResult, SimulationResult, calibrate, diagnose, load_dataset, plan, simulate
from handeye.app.results import CalibrationResult, DiagnosisResult
from handeye.model.errors import InputError

__all__ = [
    "CalibrationResult",
    "DiagnosisResult",
    "InputError",
    "PlanResult",
    "SimulationResult",
    "calibrate",
    "diagnose",
    "load_dataset",
    "plan",
    "simulate",
]
