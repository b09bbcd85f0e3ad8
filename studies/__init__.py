"""handeye's application layer: calibration runs, reports, studies and the ``handeye`` CLI."""
