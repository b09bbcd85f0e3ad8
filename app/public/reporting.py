"""``handeye report DATASET [--calibration FILE] --html OUT.html`` and ``calibrate --report``.

Stages: validate the request (output path, the saved calibration's kind and dataset) -> the
calibration (run now, or read from ``calibrate --out``'s file) -> optionally the discrepancy
workflow -> the page (:mod:`handeye.app.present.web.page`) -> written atomically. The page is
built from the calibration's JSON object, the same one ``calibrate --json`` prints, so a report
of a saved file and one of a fresh run are the same page.
"""
from __future__ import annotations

import pathlib

from handeye.app.common import options
from handeye.app.common.errors import RequestError
from handeye.app.present.web.write import ReportResult, write_report  # noqa: F401  (the command's result: public here)


def saved_result(path, dataset):
    """The JSON object of a ``calibrate --out`` file made from ``dataset`` (the same content hash),
    or :class:`RequestError` naming the file and what does not match."""
    from handeye.app.outputs.saved import CalibrationFileError, document

    file = pathlib.Path(path)
    doc = document(file)
    if not isinstance(doc, dict) or not isinstance(doc.get("residuals"), list) or "sensor_matrix" not in doc:
        raise CalibrationFileError(file, "not a whole calibration result (no residuals): give the file `handeye "
                                         "calibrate DATASET --out FILE` wrote, or score a pose with `handeye calibrate "
                                         "DATASET --calibration FILE`")
    if not isinstance(doc.get("dataset_sha256"), str):
        raise CalibrationFileError(file, "has no dataset_sha256: not a calibration of a dataset (a scored pose, or a "
                                         "file made by hand); give the file `handeye calibrate DATASET --out FILE` wrote",
                                   "dataset_sha256")
    sha = dataset.content_hash()
    if doc.get("dataset_sha256") != sha:
        raise CalibrationFileError(file, f"was made from another dataset (SHA-256 {str(doc.get('dataset_sha256'))[:12]}..., "
                                         f"{dataset.name} has {sha[:12]}...): report it on its own dataset, or score it "
                                         f"on this one with `handeye calibrate {dataset.name} --calibration {file}`",
                                   "dataset_sha256")
    from handeye.app.outputs.saved import from_document

    from_document(doc, file)  # the matrix, covariance, mount and axes as any use of the file checks them
    centre = doc.get("sphere_center")
    if not (isinstance(centre, list) and len(centre) == 3 and all(isinstance(v, (int, float)) for v in centre)):
        raise CalibrationFileError(file, "needs three numbers (mm)", "sphere_center")
    return doc


@options.COMMANDS["report"].documented
def report(dataset="thesis-real", *, html, calibration=None, diagnose=False, unknowns=None, model=None,
           convention=None, keep_all=False, no_clean=False):
    """Write the one-file HTML report of a calibration (``handeye report``).

    {parameters}

    Returns
    -------
    ReportResult
    """
    from handeye.app.common.files import check_output_path, input_files
    from handeye.app.public import api

    if calibration is not None:
        given = [o for o, v in (("--unknowns", unknowns), ("--model", model), ("--convention", convention),
                                ("--keep-all", keep_all)) if v]
        if given:
            raise RequestError(f"{', '.join(given)}: options of a calibration made now; with --calibration the file is "
                               "reported as it was made (calibrate again with them, or leave them out)")
    data = api.load_dataset(dataset, clean=not no_clean)
    check_output_path(html, "--html", inputs=input_files(data) | _input(calibration))
    if calibration is not None:
        result, source, text = saved_result(calibration, data), str(calibration), None
        if diagnose and result.get("unknowns") not in ("sensor", "sensor+sphere"):
            raise RequestError(f"--diagnose: diagnose takes --unknowns sensor or sensor+sphere; {calibration} was "
                               f"calibrated with {result.get('unknowns')}")
    else:
        res = api.calibrate(data, unknowns=unknowns or "sensor", model=model, convention=convention, keep_all=keep_all)
        result, source, text = res.to_dict(), "calibrated now", res.to_json()
    diagnosis = None
    if diagnose:
        how = result.get("unknowns") or unknowns or "sensor"
        if how not in ("sensor", "sensor+sphere"):
            raise RequestError(f"--diagnose: diagnose takes --unknowns sensor or sensor+sphere, not {how}")
        diagnosis = api.diagnose(data, unknowns=how).to_dict()
    return write_report(result, data, html, diagnosis, text, source)


def _input(calibration):
    return set() if calibration is None else {pathlib.Path(calibration).resolve()}
