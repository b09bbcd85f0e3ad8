"""A robot's configuration groups: which samples share the wrist, elbow or shoulder configuration.

A six-axis arm reaches most flange poses in up to eight configurations. Where some of a dataset's
poses are in another configuration than the rest, a robot error can act differently on the two
groups: a zero offset of j5 turns the flange about j5's axis, which a wrist flip
``(j4 + 180, -j5, j6 + 180)`` reverses, so for the same flange pose the offset acts with the
opposite sign; the sensor pose, fitted to the larger group, absorbs the offset's mean there and the
other group's samples look like gross errors. (A j4 or j6 zero offset does not: the flip turns
neither j4's axis, the forearm, nor the flange. A j6 offset is a turn about the flange's own axis in
every configuration, the sensor's rotation; a j4 offset is seen through the joint angles alike in
both.) Excluded samples that coincide with such a group are structure, not gross errors
(:func:`coinciding`); the discrepancy search then tests the group kept with the robot's effects
(:mod:`handeye.app.engine.diagnose`).

The groups (:func:`groups`), from the joint angles and the nominal model (``dataset.joints``,
``dataset.robot_model``) or from a configuration field of the controller (``dataset.configuration``,
ABB's ``cfx``: bit 0 j5 < 0, bit 1 the wrist centre behind the lower arm, bit 2 behind axis 1):

``wrist``
    j5 < 0 (the wrist flipped) or j5 > 0 (the chain's j5: the model's coupling applied);
``elbow``
    the wrist centre on one side or the other of the lower arm's line (shoulder -> elbow), seen
    along j2's axis (elbow up / down);
``shoulder``
    the wrist centre in front of or behind axis 1, along the arm's radial direction (link 1's x).

A coincidence (:func:`coinciding`) is a group holding at least :data:`MIN_SHARED` of the excluded
samples and most of them, whose share of them is improbable by chance: the hypergeometric tail of
drawing as many of the group among that many excluded samples, Bonferroni over the groups tested,
below the level ``alpha``.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from handeye.model.common.rotation import matrix_from_rotvec
from handeye.model.readers.tables import DatasetError, number

#: Fewest excluded samples a configuration group must hold to be named: one or two gross errors in
#: a group of a few poses are chance (two of 8 in 64 poses among 3 excluded: p = 0.04).
MIN_SHARED = 3
#: Angle of j5 (deg) within which a pose is at the wrist singularity and in neither wrist group.
SINGULAR_DEG = 1.0
#: ABB ``cfx`` bits (ABB RAPID ``confdata``: cfx 0-7 for a six-axis arm) and what each means.
CFX_BITS = {"wrist": (0, "j5 < 0 (the wrist flipped, cfx bit 0)", "j5 > 0 (cfx bit 0 clear)"),
            "elbow": (1, "the wrist centre behind the lower arm (cfx bit 1)", "the wrist centre in front of the lower arm"),
            "shoulder": (2, "the wrist centre behind axis 1 (cfx bit 2)", "the wrist centre in front of axis 1")}


@dataclasses.dataclass(frozen=True)
class Group:
    """One side of a configuration partition.

    Attributes
    ----------
    kind : str
        ``wrist``, ``elbow`` or ``shoulder``.
    label : str
        What its samples share, said (``"j5 < 0 (the wrist flipped)"``).
    members : ndarray of bool, shape (N,)
    source : str
        ``joints`` (the angles through the nominal model) or ``cfx`` (the controller's field).
    """

    kind: str
    label: str
    members: np.ndarray
    source: str


def _frames(model, joints_deg):
    """Per joint (N, 6): the point on its axis (N, 6, 3, mm) and the axis (N, 6, 3) in the base."""
    q = np.radians(np.asarray(joints_deg, float).reshape(-1, 6) @ model.coupling.T + model.offsets)
    frame = np.broadcast_to(model.base, (len(q), 4, 4)).copy()
    points, axes = [], []
    for j in range(6):
        at = frame @ model.origins[j]
        points.append(at[:, :3, 3])
        axes.append(at[:, :3, :3] @ model.axes[j])
        turn = np.broadcast_to(np.eye(4), (len(q), 4, 4)).copy()
        turn[:, :3, :3] = matrix_from_rotvec(model.axes[j][None, :] * q[:, j:j + 1])
        frame = at @ turn @ model.after[j]
    return np.stack(points, 1), np.stack(axes, 1), q


def _from_joints(model, joints):
    """The groups of the joint angles (module docstring): ``(kind, one side, other side, labels)``."""
    points, axes, q = _frames(model, joints)
    j5 = np.degrees(np.angle(np.exp(1j * q[:, 4])))
    shoulder, elbow, wrist = points[:, 1], points[:, 2], points[:, 4]
    line = (wrist - shoulder) / np.linalg.norm(wrist - shoulder, axis=1, keepdims=True)
    bend = (elbow - shoulder) - np.einsum("ni,ni->n", elbow - shoulder, line)[:, None] * line
    up = bend @ (model.base[:3, :3] @ [0.0, 0.0, 1.0])  # the elbow above the shoulder-wrist line
    a1 = axes[:, 0]
    radial = shoulder - points[:, 0]
    radial -= np.einsum("ni,ni->n", radial, a1)[:, None] * a1
    small = np.linalg.norm(radial, axis=1) < 1.0  # no shoulder offset: normal to axes 1 and 2
    radial[small] = np.cross(axes[small, 1], a1[small])
    ahead = np.einsum("ni,ni->n", wrist - points[:, 0], radial)
    return [("wrist", j5 < -SINGULAR_DEG, j5 > SINGULAR_DEG, "j5 < 0 (the wrist flipped)", "j5 > 0"),
            ("elbow", up < -1.0, up > 1.0, "the elbow down (below the shoulder-wrist line)", "the elbow up"),
            ("shoulder", ahead < -1.0, ahead > 1.0, "the wrist centre behind axis 1", "the wrist centre in front of axis 1")]


def groups(dataset):
    """The configuration groups of a dataset's samples (module docstring), both sides of each
    partition that splits them: from the joint angles when given, else from the ``cfx`` column; []
    without either."""
    raw = []
    cfx = getattr(dataset, "configuration", None)
    if getattr(dataset, "joints", None) is not None and getattr(dataset, "robot_model", None) is not None:
        raw = [(*g, "joints") for g in _from_joints(dataset.robot_model, dataset.joints)]
    elif cfx is not None:
        cfx = np.asarray(cfx, int)
        raw = [(kind, (cfx >> bit) & 1 == 1, (cfx >> bit) & 1 == 0, on, off, "cfx")
               for kind, (bit, on, off) in CFX_BITS.items()]
    out = []
    for kind, one, other, label_one, label_other, source in raw:
        if one.any() and other.any():
            out += [Group(kind, label_one, one, source), Group(kind, label_other, other, source)]
    return out


def _tail(total, group, drawn, shared):
    """P(at least ``shared`` of ``drawn`` samples drawn at random from ``total`` lie in a group of ``group``)."""
    denominator = math.comb(total, drawn)
    return sum(math.comb(group, k) * math.comb(total - group, drawn - k)
               for k in range(shared, min(group, drawn) + 1)) / denominator


@dataclasses.dataclass(frozen=True)
class Coincidence:
    """Excluded samples that coincide with a configuration group.

    Attributes
    ----------
    group : Group
    shared : int
        Excluded samples in the group.
    excluded : int
        Samples excluded.
    p : float
        The hypergeometric tail, Bonferroni over the groups tested.
    """

    group: Group
    shared: int
    excluded: int
    p: float

    def said(self):
        """``"the 8 excluded samples are the 8 with j5 < 0 (the wrist flipped)"``."""
        size = int(self.group.members.sum())
        whole = f"the {size}" if self.shared == size else f"{self.shared} of the {size}"
        which = (f"the {self.excluded} excluded samples are {whole}" if self.shared == self.excluded
                 else f"{self.shared} of the {self.excluded} excluded samples are {whole}")
        return (f"{which} with {self.group.label} (from the {'joint angles' if self.group.source == 'joints' else 'cfx column'}"
                f"; by chance p = {self.p:.2g}): a configuration group, not gross errors")


def coinciding(dataset, excluded, alpha):
    """The configuration group the ``excluded`` samples (bool, shape (N,)) coincide with (module
    docstring), or None."""
    excluded = np.asarray(excluded, bool)
    found, n, e = groups(dataset), len(excluded), int(excluded.sum())
    best = None
    for g in found:
        shared = int((g.members & excluded).sum())
        if shared < MIN_SHARED or 2 * shared <= e:
            continue
        p = min(1.0, _tail(n, int(g.members.sum()), e, shared) * len(found))
        if p < alpha and (best is None or p < best.p):
            best = Coincidence(g, shared, e, p)
    return best


def cfx_field(text, file, line):
    """ABB's ``cfx`` of a row of ``measurements.csv`` (RAPID ``confdata``: an integer 0-7, :data:`CFX_BITS`)."""
    value = number(text, file, line, "cfx")
    if value not in range(8):
        raise DatasetError(file, f"{text.strip()!r} is no ABB cfx (an integer 0-7)", line, "cfx")
    return value


def split_cfx(angles, n_axes):
    """``(angles, cfx)``: a dataset's angle columns (positioner axes, joints) and its ``cfx`` (int, or None
    without the column), which the row reader puts after the joints (one column more than the axes and
    six joints)."""
    if (angles.shape[1] - n_axes) % 6 != 1:
        return angles, None
    return angles[:, :-1], angles[:, -1].astype(int)
