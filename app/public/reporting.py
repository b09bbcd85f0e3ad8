"""``handeye report DATASET [--calibration FILE] --html OUT.html`` and ``calibrate --report``.

Stages: load the dataset -> the request (:class:`ReportRequest`: the options, the output path, the
saved calibration's kind and dataset) -> the calibration (run now, or read from ``calibrate
--out``'s file) -> optionally the discrepancy workflow -> the page (:mod:`handeye.app.present.web.page`)
-> written atomically. The page is built from the calibration's JSON object, the same one
``calibrate --json`` prints, so a report of a saved file and one of a fresh run are the same page.
"""
from __future__ import annotations

import dataclasses
import pathlib

import numpy as np

from handeye.app.common import options
from handeye.app.common.errors import RequestError
from handeye.app.common.files import check_output_path, input_files
from handeye.app.engine.request import UNKNOWNS, unknown_parts
from handeye.app.outputs import verdict as verdicts
from handeye.app.outputs.saved import CalibrationFileError, document, from_document
from handeye.app.present.web.write import Page, write_report


def saved_result(path, dataset):
    """The JSON object of a ``calibrate --out`` file made from ``dataset`` (the same content hash),
    or :class:`RequestError` naming the file and what does not match."""
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
    from_document(doc, file)  # the matrix, covariance, mount and axes as any use of the file checks them
    centre = doc.get("sphere_center")
    if not (isinstance(centre, list) and len(centre) == 3 and all(isinstance(v, (int, float)) for v in centre)):
        raise CalibrationFileError(file, "needs three numbers (mm)", "sphere_center")
    return doc


def recomputed(doc, file, data):
    """The page's object of a saved calibration ``doc`` (the file ``file``) of ``data``: its verdict
    (status, RMS and residuals, noise test, sensor sd) recomputed from the data at its pose
    (:func:`handeye.app.outputs.verdict.check`), each field that disagrees named in ``warnings``,
    the recomputation in ``recomputed``; :class:`CalibrationFileError` (exit 2) when that makes the
    file unusable (a mount not the dataset's, a pose the data contradict)."""
    checked = verdicts.check(file, from_document(doc, file).for_dataset(data.own_axes), dataset=data)
    v = checked.verdict
    out = {**doc, "warnings": [*checked.notes, *(doc.get("warnings") or [])],
           "recomputed": {"verdict": checked.status, "notes": list(checked.notes), "failed": v.failed()}}
    if v.not_recomputed:
        return out
    rows = {sid: k for k, sid in enumerate(data.ids)}
    out["residuals"] = [r if not isinstance(r, dict) or r.get("id") not in rows else
                        {**r, "vector": v.residuals[rows[r["id"]]].tolist(),
                         "norm": float(np.linalg.norm(v.residuals[rows[r["id"]]]))} for r in doc.get("residuals") or []]
    out.update(rms_mm=v.rms_mm, max_residual_mm=v.max_mm, n_used=int(v.used.sum()),
               noise_test=None if v.noise is None else v.noise.to_dict())
    sd = checked.calibration.user_frame().sd()
    if sd is not None and isinstance(doc.get("std"), dict):
        out["std"] = {**doc["std"], "sensor_translation_mm": sd[0].tolist(), "sensor_rotation_deg": sd[1].tolist()}
    return out


@dataclasses.dataclass(frozen=True)
class ReportRequest:
    """``handeye report``'s options, checked against the dataset.

    Attributes
    ----------
    saved : dict or None
        The saved calibration's JSON object (:func:`saved_result`); None: calibrate now.
    source : str
        ``calibrated now`` or the saved file's name.
    diagnose : str or None
        The unknowns the discrepancy workflow runs with (the calibration's); None: not run.
    """

    saved: dict | None
    source: str
    diagnose: str | None

    @classmethod
    def from_options(cls, v, data):
        """The request of the options ``v`` (the public function's keywords) on ``data``."""
        file = v["calibration"]
        given = [o for o, key in (("--unknowns", "unknowns"), ("--model", "model"), ("--convention", "convention"),
                                  ("--keep-all", "keep_all")) if v[key]]
        if file is not None and given:
            raise RequestError(f"{', '.join(given)}: options of a calibration made now; with --calibration the file is "
                               "reported as it was made (calibrate again with them, or leave them out)")
        inputs = input_files(data) | (set() if file is None else {pathlib.Path(file).resolve()})
        check_output_path(v["html"], "--html", inputs=inputs)
        doc, source = (None, "calibrated now") if file is None else (saved_result(file, data), str(file))
        if not v["diagnose"]:
            return cls(doc, source, None)
        how = unknown_parts(v["unknowns"] or "sensor") if doc is None else doc.get("unknowns")
        if how not in UNKNOWNS:
            raise RequestError("--diagnose: diagnose takes --unknowns sensor or sensor+sphere"
                               + (f", not {how}" if doc is None else f"; {file} was calibrated with {how}"))
        return cls(doc, source, how)


@options.COMMANDS["report"].documented
def report(dataset="thesis-real", *, html, calibration=None, diagnose=False, unknowns=None, model=None,
           convention=None, keep_all=False, no_clean=False):
    """Write the one-file HTML report of a calibration (``handeye report``).

    {parameters}

    Returns
    -------
    handeye.app.present.web.write.ReportResult
    """
    from handeye.app.public import api

    given = options.COMMANDS["report"].given(locals())
    data = api.load_dataset(dataset, clean=not no_clean)
    request = ReportRequest.from_options(given, data)
    if request.saved is not None:
        result, text = recomputed(request.saved, request.source, data), None
    else:
        res = api.calibrate(data, unknowns=unknowns or "sensor", model=model, convention=convention, keep_all=keep_all)
        result, text = res.to_dict(), res.to_json()
    diagnosis = None if request.diagnose is None else api.diagnose(data, unknowns=request.diagnose).to_dict()
    return write_report(Page(result, data, diagnosis, text, request.source), html)
