"""The verdict's levels: every significance level and factor by which calibrate judges an alternative
reading of the data, in one place, each with the argument for its value.

The alternatives (a setup slip, a held part, a fit that explains nothing, a second group of samples,
another robot model, a closed-form baseline, a saved file's fields) are each judged the same way: a test
of the two sums of squares at a level (nested: an F test; not nested: Delta BIC) *and* a size that matters
(an RMS factor, a distance in mm and degrees), so that a large dataset's power does not turn a difference
no robot would notice into a refusal, and a small dataset's noise does not hide one that matters. The
modules that judge import their levels from here; the values are the ones the independent generators'
rates were measured with (README, "What exit 0 promises, measured").
"""
from __future__ import annotations

# -- a setup slip (app/engine/slips.py): a re-reading of the data that fits clearly better ---------------
#: A plain fit with a larger RMS (mm), or residuals above the stated noise, is checked for slips.
SUSPECT_RMS_MM = 1.0
#: Level of the chi-square test against the stated noise that makes a fit suspect.
P_SUSPECT = 0.01
#: Undoing a slip must lower the RMS by at least this factor ...
FACTOR = 2.0
#: ... with the F test of the two sums of squares below this p-value (a slip named is exit 2: a false one
#: stops good data, so the level is a hundred times the outlier tests') ...
P_SLIP = 1e-4
#: ... and leave at most this RMS (mm).
EXPLAINED_RMS_MM = 2.0
#: Profiles and the sensor's own centres must agree on the sphere's radius within this fraction
#: (or DIAMETER_AGREE_MM, whichever is larger) and six standard errors of their median.
DIAMETER_AGREE = 0.005
DIAMETER_AGREE_MM = 0.1
#: A centre within this fraction of the sphere radius of the laser plane is near the equator.
EQUATOR_BAND = 0.1
#: The rows near the equator decide the side unless flipping them changes the fit less than
#: an F test at this level can see ...
P_SIDE = 1e-3
#: ... while moving the pose by more than this (mm, deg) and more than SIDE_MOVE_SD of its
#: standard deviations.
SIDE_MOVE_MM, SIDE_MOVE_DEG, SIDE_MOVE_SD = 1.0, 0.5, 3.0

# -- a fit that explains nothing, two groups (app/engine/guarantee.py) ------------------------------------
#: The final fit's centres may scatter this much more than at the centre model's global
#: minimum (RMS ratio) plus CROSS_CHECK_SIGMAS stated sd before the fit is refused.
CROSS_CHECK_RATIO, CROSS_CHECK_SIGMAS = 2.0, 3.0
#: Above this fraction of the motion the sensor sees (:func:`handeye.app.engine.guarantee.motion_seen`)
#: the residual RMS of the centre model's global minimum means the model explains nothing: a model that is right
#: leaves the noise and the cell's unmodelled effects (RMS / motion: thesis-real's base model,
#: its taught centre millimetres off, 0.054; the robcalibrator sets in tests/data 0.010-0.058;
#: 0.05 deg of joint offset on rotations about the sphere 0.006; clean simulated cells
#: 0.0003-0.0015), while data whose pairing or convention is wrong leave a fraction of the
#: motion itself (simulated tours with the sensor fixed, shifted by one row: 0.24-0.39).
EXPLAINS_NOTHING = 0.1
#: ... or above this fraction of the spread of the sensor's measured centres about their mean
#: (at 1, the fitted pose predicts them no better than their mean does).
EXPLAINS_NOTHING_SENSOR = 1.0
#: ... and only when the residuals are also above the stated noise at this level.
NOISE_P = 1e-3
#: Rows the screening excluded that fit each other this well (RMS ratio to the used rows' or
#: the stated noise's, whichever is larger) ...
GROUP_AGREE = 2.0
#: ... at a pose this far from the reported one (mm, deg) are a second group, not gross errors.
GROUP_APART_MM, GROUP_APART_DEG = 2.0, 1.0

# -- the fit against the stated noise, and what remains (app/engine/describe.py, diagnose.py) -----------
#: Level of the test of the fit against the stated noise (a warning; strict, so that clean data
#: of a slightly miscalibrated noise model are not flagged: 2 of 120 clean runs at 0.01).
NOISE_ALPHA = 0.001
#: chi2/dof below which a fit leaves nothing beyond the nominal noise (diagnose's line between
#: "nothing beyond the nominal noise" and "an effect outside the catalogue remains"; the configuration
#: group's test of a group kept with an effect).
AT_NOISE = 2.0
#: A residual this many robust standard deviations above the median is flagged.
GROSS_ERROR_Z = 10.0
#: A widened uncertainty is warned of where the widening (what the data could not see,
#: app/engine/search.py) grows a pose component's sd by more than this factor: the upper end of the band in
#: which a reported sd counts as right (observed / reported 0.8-1.25, the independent generators' checks); a
#: smaller widening (30 poses at 0.05 mm: 1-5 %) is said in the report's power line and the JSON only.
POWER_WARN_GROWTH = 1.25

# -- a depth bend of the profiles corrected (app/engine/bend.py, model/geometry/profile_bend.py) ---------------
#: The fraction of the pose's move by a bend correction (mm, and rad, each block's length) added as 1 sd of doubt
#: to every component of its block. The correction is a polynomial in depth fitted through the circles; its
#: jackknife covers the profiles' scatter, not the shape the polynomial and the circles trade between them, which
#: the rebuilt y amplifies r / |y| times. Measured where the truth is known: on ``simulate --linearity`` (sine
#: bends, 11 cells) the pose kept 8-21 % of the move away from the truth; on an independent generator's quadratic,
#: cubic, sine and piecewise bends (tests/indep_linearity.py) the median error fell to 20-45 % of the
#: uncorrected one. A fifth as 1 sd keeps 60 % within 3 sd.
BEND_DOUBT = 0.2

# -- one model fitted twice: the search's pose against calibrate's (app/engine/agreement.py, search.py) ----
#: Two poses are the same when they lie within this many sd of the reported one (Mahalanobis distance in
#: its covariance, 6 dof) -- or closer than AGREE_FLOOR (mm, deg), where a noise-free fit's sd is itself
#: rounding. The same model fitted twice (other residual weights, other outlier decisions) differs by
#: 0.00-0.17 sd on 25 clean simulated cells (5 mounts and sensors, 12-36 poses); a pose under a model
#: the data contradict, by 3-45 sd.
AGREE_SD = 1.0
AGREE_FLOOR = (1e-3, 1e-3)
#: The search's fit in the rebuilt centres' first-order metric and calibrate's of the measured circles (the
#: exact likelihood) are one model in two metrics: calibrate's stands where they lie within this many of its
#: sd (10 poses of a 1-inch ball, where the first order is poorest: 1.55 sd); beyond, the two disagree by more
#: than a metric explains (a fit in another minimum, say) and the diagnosis keeps its own pose and says so.
METRIC_SD = 3.0

# -- a part held (app/engine/cell_stage.py, app/engine/score.py, app/engine/held_effects.py) ---------------
#: A held part is contradicted by the data when the fit estimating it is better at this level (F test) ...
P_HELD = 1e-3
#: ... and lowers the RMS by at least this factor (a part held from another calibration of the same cell
#: differs by its own sd, which a large dataset finds significant but not this large).
HELD_FACTOR = 1.2
#: A sensor origin (or a sphere centre on the flange) farther than this from its mount's origin (mm)
#: is implausible for a part carried on the flange: the cell is probably another one ...
FAR_ON_FLANGE_MM = 600.0
#: ... said between the two only when the other cell does not fit clearly worse (a real line scanner's
#: 874 mm on a FANUC flange fits 1.04 mm the other way against 0.18 mm), always beyond this (mm).
SURELY_FAR_MM = 1000.0

# -- not nested: the robot's errors (app/engine/robot_choice.py) ------------------------------------------
#: BIC difference below which another combination of robot effects is an alternative (Kass & Raftery); the
#: difference by which another data effect must beat a wrong diameter's radius for the slip not to be named
#: (app/engine/taught_sphere.py, _rival: a sensor's scale).
AMBIGUOUS = 10.0
#: BIC difference by which another combination must beat the searched one to replace it.
POSITIVE = 2.0

# -- an answer the tool knows to be worse (app/engine/classic.py) -----------------------------------------
#: A baseline (no sd of its own) is right within AWAY (mm, deg) of the truth, the issue's floor; the truth
#: lies within AWAY_SD of the data's own calibration's sd: the baseline's distance from that calibration
#: plus AWAY_SD of its sd must stay within AWAY.
AWAY_SD = 3.0
AWAY = (0.2, 0.05)

# -- a saved file's claims (app/engine/held_verdict.py) ---------------------------------------------------
#: Relative difference of the file's RMS from the data's beyond which the file's ``rms_mm`` is
#: named. The same samples at the same pose give the same RMS to rounding (17 digits written;
#: a freed centre refitted with the pose held lands on the file's to the solver's tolerance,
#: where the RMS is stationary): a thousandth is far above both and far below any edit that matters.
RMS_AGREES = 1e-3
#: The band of (file's sd / data's sd) per pose component within which the file's covariance
#: agrees: the band in which the project calls an sd calibrated (0.8-1.25, issue 39); the same
#: model at the same pose gives the same covariance to rounding.
SD_BAND = (0.8, 1.25)
#: The file's ``sensor_matrix`` against its own ``sensor_pose_as`` (both written from one 4x4 with
#: 17 digits): beyond this (mm, deg) one of them was edited. A file re-saved with 6 significant
#: digits moves a 2 m translation by 1e-3 mm; a calibration's sd is rarely below 0.01 mm.
POSE_AGREES = (0.01, 0.01)
