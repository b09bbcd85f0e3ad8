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
    handeye.new_dataset("mycell", poses="poses.csv", profiles="scans/", diameter=50.8)  # from loose files
    handeye.export("result.json", format="ur")     # after calibrate --out result.json
    handeye.cloud("my-scan", "result.json", out="scan.ply")
    handeye.validate("sphere-scan", "result.json")  # VDI/VDE 2634-2 PF, PS, SD

For solver studies and teaching: ``handeye.testfunction_problem()`` and
``handeye.calibration_problem(model)`` are :class:`handeye.solvers.Problem` objects that
``handeye.solvers.solve(problem, x0, method)`` minimises (``model``: a
:class:`handeye.model.fit.calibration.CalibrationModel`).

Bad input raises :class:`InputError` (a ``ValueError``), naming file, row and column or the
option. The layers: :mod:`handeye.solvers` (knows nothing of robots) <- :mod:`handeye.model`
(the mathematics, derived once) <- :mod:`handeye.app` (calibrate, diagnose, reports, CLI) <-
:mod:`handeye.studies` (studies that assert their claims).
"""
import importlib

#: public name -> module that defines it; imported on first use (PEP 562), so that importing a
#: lower layer (``import handeye.solvers``) loads nothing of the application.
_PUBLIC = {
    "load_dataset": "handeye.app.public.api",
    "calibrate": "handeye.app.public.api",
    "diagnose": "handeye.app.public.api",
    "compare": "handeye.app.public.api",
    "report": "handeye.app.public.reporting",
    "ReportResult": "handeye.app.present.web.write",
    "simulate": "handeye.app.public.api",
    "plan": "handeye.app.public.api",
    "new_dataset": "handeye.app.ingest.command",
    "NewDatasetResult": "handeye.app.ingest.command",
    "export": "handeye.app.outputs.commands",
    "cloud": "handeye.app.outputs.commands",
    "validate": "handeye.app.outputs.commands",
    "ExportResult": "handeye.app.outputs.commands",
    "CloudResult": "handeye.app.outputs.commands",
    "ValidationResult": "handeye.app.outputs.validate",
    "PlanResult": "handeye.app.public.api",
    "SimulationResult": "handeye.app.public.api",
    "CalibrationResult": "handeye.app.present.results",
    "DiagnosisResult": "handeye.app.present.diagnosis_results",
    "ScoreResult": "handeye.app.present.score_results",
    "CompareResult": "handeye.app.present.score_results",
    "InputError": "handeye.model.common.errors",
    "testfunction_problem": "handeye.app.engine.problems",
    "calibration_problem": "handeye.app.engine.problems",
}
__all__ = sorted(_PUBLIC)


def __getattr__(name):
    if name in _PUBLIC:
        value = getattr(importlib.import_module(_PUBLIC[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'handeye' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_PUBLIC))
