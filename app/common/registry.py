"""The studies ``handeye study NAME`` runs (name -> module, as strings), and how a claim fails.

The application layer names the studies but never imports them (studies sit above it); the
CLI imports :mod:`handeye.studies.study` only when ``handeye study`` runs.
"""
from __future__ import annotations

#: study name -> module (each has ``run(out, quick) -> dict``)
STUDIES = {
    "testfunction": "handeye.studies.study_testfunction",
    "start-poses": "handeye.studies.study_start_poses",
    "real-data": "handeye.studies.study_real_data",
    "circle-fits": "handeye.studies.study_circle_fits",
    "accuracy": "handeye.studies.study_accuracy",
    "random-starts": "handeye.studies.study_random_starts",
    "pose-planning": "handeye.studies.study_planning",
    "discrepancy-power": "handeye.studies.study_power",
    "classics": "handeye.studies.study_classics",
    "honest-default": "handeye.studies.study_default",
    "batch-equivalence": "handeye.studies.study_batch",
    "global-guarantee": "handeye.studies.study_guarantee",
    "mounts": "handeye.studies.study_mounts",
    "thesis-robot": "handeye.studies.study_thesis_robot",
}


class StudyClaimFailed(AssertionError):
    """A study's data did not support its claim (``handeye study`` exits 4)."""
