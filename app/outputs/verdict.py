"""What an output (``export``, ``cloud``, ``validate``) says of a saved calibration's verdict:
recomputed from its dataset (:mod:`handeye.app.engine.held_verdict`), never copied from the file.

The dataset is the one the command reads when it is the file's own (the same SHA-256), else the
one ``export --dataset`` names, else the file's own ``dataset_path`` when it is still there and
still hashes to the file's ``dataset_sha256``. Without one, only the file's own fields are
checked against each other, and the output says the verdict is the file's, not recomputed.

A disagreement that makes the file unusable is :class:`handeye.app.outputs.saved.CalibrationFileError`
(exit 2) naming the file and the field, with the recomputed verdict; the others are notes.
"""
from __future__ import annotations

import dataclasses
import pathlib

from handeye.app.common.arguments import load_dataset
from handeye.app.engine import held_verdict
from handeye.app.engine.describe import NOISE_WARNING
from handeye.app.outputs import saved
from handeye.app.present.report import WARNING_CHARS, shorten  # noqa: F401  (the report's, the outputs' too)
from handeye.model.common.errors import InputError


@dataclasses.dataclass(frozen=True)
class Checked:
    """A saved calibration's verdict as an output states it.

    Attributes
    ----------
    calibration : handeye.app.outputs.saved.Calibration
        The calibration, its covariance the recomputed one where the data gave it.
    verdict : handeye.app.engine.held_verdict.HeldVerdict or None
        Recomputed on its dataset; None without one.
    notes : tuple of str
        The file named as hand-edited or foreign, one line per field (empty for a good file).
    warnings : tuple of str
        The file's own warnings (its ``warnings``).
    status : str
        The calibration's status in one line (recomputed, or the file's and said so).
    """

    calibration: object
    verdict: object = None
    notes: tuple = ()
    warnings: tuple = ()
    status: str = ""

    @property
    def failed(self):
        """The failed checks: the file's warnings, the recomputation's and the notes, each one short line."""
        again = () if self.verdict is None else tuple(self.verdict.failed())
        mine = self.warnings if self.verdict is None or self.verdict.noise is None or self.verdict.not_recomputed else tuple(
            w for w in self.warnings if not w.startswith(NOISE_WARNING))  # the recomputed test says it
        return tuple(shorten(w) for w in (*mine, *again)) + self.notes


def _own_dataset(doc, folder, given, folder_hash=None):
    """The Dataset to recompute on (module docstring), or None; and a :class:`Disagreement` when
    the dataset given (``--dataset``) or the file's own ``dataset_path`` hashes to another SHA-256
    (a foreign file, or a dataset changed since). The command's own folder may be other data (a
    scan held out): not a disagreement."""
    sha = doc.get("dataset_sha256")
    if not isinstance(sha, str):
        return None, None
    changed = None
    for path, named in ((given, True), (folder, False), (doc.get("dataset_path"), True)):
        if path is None or (path is folder and folder_hash is not None and folder_hash != sha):
            continue  # the command's own data, hashed already: another dataset (a scan held out), not loaded
        try:
            data = load_dataset(path, clean=not _no_clean(doc))
        except (InputError, OSError, TypeError, ValueError):
            continue  # not a calibration dataset (a scan without a sphere), or gone
        if data.content_hash() == sha:
            return data, changed
        if named and changed is None:
            changed = held_verdict.Disagreement("dataset_sha256", f"{sha[:12]}...", f"{path} hashes to "
                                                f"{data.content_hash()[:12]}... (another dataset, or changed since)")
    return None, changed


def _no_clean(doc):
    options = (doc.get("provenance") or {}).get("options") if isinstance(doc.get("provenance"), dict) else None
    return bool(isinstance(options, dict) and options.get("no_clean"))


def check(calibration, cal, folder=None, dataset=None, folder_hash=None):
    """The :class:`Checked` verdict of ``cal`` (held from ``calibration``: a saved file's name, or
    anything else: a pose typed in or a result in memory, checked by nothing here), on the
    command's ``folder`` (its SHA-256 ``folder_hash`` when the command has it: another one is not
    loaded again) or ``dataset`` (module docstring)."""
    if hasattr(calibration, "to_dict") and hasattr(calibration, "sensor2flange"):  # a result in memory
        file, doc = cal.source, calibration.to_dict()
    elif isinstance(calibration, (str, pathlib.Path)):
        file = pathlib.Path(calibration)
        doc = saved.document(file)
    else:
        return Checked(cal, status=_typed_status(cal))
    data, changed = _own_dataset(doc, folder, dataset, folder_hash)
    changed = [changed] if changed else []
    warnings = tuple(w for w in doc.get("warnings") or [] if isinstance(w, str))
    if data is None:
        found = held_verdict.own_disagreements(doc) + changed
        _refuse(file, found, None)
        return Checked(cal, None, tuple(d.line(file) for d in found), warnings, _file_status(doc))
    data = _at_axes(cal, data)
    verdict = held_verdict.recompute(doc, cal.for_dataset(data.own_axes).sensor2flange, data)
    verdict = dataclasses.replace(verdict, disagreements=(*verdict.disagreements, *changed))
    _refuse(file, verdict.disagreements, verdict)
    keep = verdict.not_recomputed or cal.positioner_axes  # the file's sd holds what the plain chain cannot
    held = cal if keep or cal.covariance is None else dataclasses.replace(cal, covariance=verdict.covariance)
    converged = doc.get("converged", True) is True and (verdict.converged or bool(verdict.not_recomputed))
    status = f"{'converged' if converged else 'NOT CONVERGED'}{_said(doc, verdict)}: {verdict.line()}"
    return Checked(held, verdict, tuple(d.line(file) for d in verdict.disagreements), warnings, status)


def _at_axes(cal, data):
    """``data`` at the positioner axes ``cal`` holds (as set up when it holds none)."""
    mounts = getattr(data, "mounts", None)
    if not cal.positioner_axes or mounts is None or mounts.sphere != "positioner":
        return data
    return dataclasses.replace(data, mounts=mounts.at(cal.positioner_axes))


def _refuse(file, disagreements, verdict):
    """:class:`saved.CalibrationFileError` for the first fatal disagreement, with the recomputed verdict."""
    fatal = [d for d in disagreements if d.fatal]
    if fatal:
        more = "" if verdict is None or fatal[0].key == "sensor_mount" else f"; {verdict.line()}"
        raise saved.CalibrationFileError(file, fatal[0].text() + more, fatal[0].key)


def _said(doc, verdict):
    """What the status is of where the data could not recompute it (effects): the file's RMS, its word."""
    if not verdict.not_recomputed:
        return ""
    rms = doc.get("rms_mm")
    return (f", RMS {rms:.4g} mm" if isinstance(rms, (int, float)) else "") + " as the file says"


def _file_status(doc):
    converged = doc.get("converged", True) is True
    rms = doc.get("rms_mm")
    rms = f", RMS {rms:.4g} mm" if isinstance(rms, (int, float)) else ""
    return (f"{'converged' if converged else 'NOT CONVERGED'}{rms} as the file says, not recomputed (no dataset of its "
            "SHA-256 at hand: give --dataset, or keep the file's dataset_path)")


def comment_lines(checked, forced=None):
    """The lines an export writes as comments: ``FORCED ...`` first when ``forced`` (why the
    calibration is no calibration: it is written only because of ``--force``), the status, and
    every failed check or warning (``warning: ...``: a widened sd is no failure), one short line each."""
    lines = [f"FORCED (written with the force option): NOT a calibration: {shorten(forced)}"] if forced else []
    return lines + [f"verdict: {checked.status}"] + [f"warning: {w}" for w in checked.failed]


def _typed_status(cal):
    return f"a pose given ({cal.source}), not a calibration checked here: no verdict"
