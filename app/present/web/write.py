"""The report written: :func:`write_report` (the page of a calibration's JSON object, :class:`Page`,
atomically) and what it wrote, :class:`ReportResult`."""
from __future__ import annotations

import dataclasses

from handeye.app.present.protocol import ResultProtocol
from handeye.app.present.result_parts import AsDict


@dataclasses.dataclass(frozen=True)
class ReportResult(AsDict, ResultProtocol):
    """What ``handeye report`` wrote.

    Attributes
    ----------
    path : str
        The HTML file.
    size_bytes : int
    interactive : bool
        True when the 3-D view is plotly's (the ``report`` extra), False for the static picture.
    dataset : str
    source : str
        ``calibrated now`` or the saved calibration's file.
    converged : bool
        The reported calibration's own flag (the CLI exits 1 when False; the report says why).
    samples, excluded : int
    diagnosed : bool
        The discrepancy workflow's steps are in the report.
    """

    path: str
    size_bytes: int
    interactive: bool
    dataset: str
    source: str
    converged: bool
    samples: int
    excluded: int
    diagnosed: bool

    def summary(self):
        view = ("interactive 3-D view (plotly)" if self.interactive
                else "static 3-D picture (pip install 'handeye[report]' for the interactive view)")
        state = "converged" if self.converged else "NOT CONVERGED (the report says why)"
        return (f"report written: {self.path} ({self.size_bytes / 1e6:.2f} MB, {view})\n"
                f"calibration of {self.dataset} ({self.source}): {state}; {self.samples} samples, {self.excluded} excluded"
                + ("; diagnose steps included" if self.diagnosed else ""))


@dataclasses.dataclass(frozen=True)
class Page:
    """What a report shows: ``result`` (a calibration's JSON object) on ``dataset``, the
    discrepancy workflow's ``diagnosis`` (None: not run), ``result_json`` (the text ``calibrate
    --json`` prints, embedded as it is; None: made from ``result``) and its ``source``
    (``calibrated now`` or the saved file)."""

    result: dict
    dataset: object
    diagnosis: dict | None = None
    result_json: str | None = None
    source: str = "calibrated now"


def write_report(page, html, option="--html"):
    """Build the :class:`Page` and write it to ``html`` atomically; the :class:`ReportResult`."""
    from handeye.app.common.files import write_text_atomically
    from handeye.app.present.web import page as pages
    from handeye.app.present.web import view

    result, how = page.result, (page.result, page.dataset, page.diagnosis, page.result_json)
    if page.source == "calibrated now":
        text = pages.build(*how)
    else:  # a file: what its checks let through and the page still cannot read is named, never a traceback
        from handeye.app.outputs.saved import CalibrationFileError

        try:
            text = pages.build(*how, page.source)
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise CalibrationFileError(page.source, f"cannot be reported: {type(exc).__name__}: {str(exc)[:120]}") from None
    write_text_atomically(html, text, option=option)
    return ReportResult(str(html), len(text.encode("utf-8")), view.have_plotly(), str(result.get("dataset")), page.source,
                        bool(result.get("converged")), len(result.get("residuals") or []),
                        len(result.get("excluded") or []), page.diagnosis is not None)
