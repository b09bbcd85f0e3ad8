"""``outlier``: gross errors (misprints, bad profiles). Discrete: a set of sample ids, excluded
by the robust screening and confirmed by the final deletion test (:mod:`handeye.app.engine.robust`)."""
KIND = "discrete"
NAME = "outlier"
PARAMS = ("ids",)
DOC = "samples excluded as gross errors"
