"""Which profile belongs to which pose: by a number in the file name, or by order.

Profile files are taken in natural order (``p2`` before ``p10``) within each ``--profiles``
argument. ``pair='id'`` matches a number in each profile's name (the last run of digits of the
file's stem, or of its key when a file holds several profiles; ``--match REGEX`` with one group
instead) against the pose ids (numerically when both are integers); without an id column the poses
are numbered 1..N, or 0..N-1 when the names are. ``pair='order'`` takes the k-th profile for the
k-th pose. ``pair='auto'`` (the default) pairs by id when every name's last number (or else every
name's first number: ``7_3C_line``) matches a different pose, by order when no name has one; a
partial match is an error (a missing or extra file).
"""
from __future__ import annotations

import dataclasses
import re

from handeye.model.readers.tables import DatasetError

DEFAULT_MATCH = r"(\d+)(?!.*\d)"


@dataclasses.dataclass(frozen=True)
class Pairing:
    """How profiles are paired with poses: ``mode`` (``--pair``: auto, id, order) and ``match``
    (``--match``: a regex with one group, checked by :mod:`handeye.app.ingest.request`; None: the
    name's digits)."""

    mode: str = "auto"
    match: str | None = None


AUTO = Pairing()


def natural_key(text):
    """Sort key that orders embedded numbers by value (``p2`` < ``p10``)."""
    return [(0, len(_number(t)), _number(t), t) if t.isdigit() else (1, 0, t.lower(), t)
            for t in re.split(r"(\d+)", str(text)) if t]


def _token(name, pattern):
    m = re.search(pattern, name)
    return None if m is None else m.group(1)


def _number(digits):
    """A run of digits as the text of its value (``007`` -> ``7``): compared as text, never made an
    int (a 5,000-digit name stays cheap)."""
    return digits.lstrip("0") or "0"


class _Ids:
    """The pose ids looked up by a name's token in a dict, not by a scan of every id (issue 40:
    2,000 profiles took 17 s CPU): a token matches an id of the same text, or of the same number
    as the id's last digits (``007`` is pose ``7`` and pose ``P7``)."""

    def __init__(self, pose_ids):
        self.text, self.number = {}, {}
        for k, ident in enumerate(pose_ids):
            self.text.setdefault(ident, []).append(k)
            digits = re.findall(r"\d+", ident)
            if digits:
                self.number.setdefault(_number(digits[-1]), []).append(k)

    def hits(self, token):
        """Indices of the poses ``token`` names, in the poses' order."""
        found = set(self.text.get(token, ()))
        if token.isdigit():
            found.update(self.number.get(_number(token), ()))
        return sorted(found)


def _by_id(labels, names, pose_ids, tokens, pose_file):
    """Pose index of each profile; errors name the file."""
    index, taken, lookup = [], {}, _Ids(pose_ids)
    for label, name, token in zip(labels, names, tokens):
        if token is None:
            raise DatasetError(label, f"no id in the name {name!r} (--match takes a regex with one group)")
        hits = lookup.hits(token)
        if not hits:
            shown = ", ".join(pose_ids[:3]) + (", ..." if len(pose_ids) > 3 else "")
            raise DatasetError(label, f"id {token[:40]!r} is not a pose id of {pose_file} (ids {shown})")
        if hits[0] in taken:
            raise DatasetError(label, f"is pose {pose_ids[hits[0]]!r}, as {taken[hits[0]]} is: two profiles of one pose")
        taken[hits[0]] = label
        index.append(hits[0])
    return index


def pair(labels, names, pose_ids, n_poses, pose_file, asked=AUTO):
    """Pose index of each profile and a description of the pairing.

    Parameters
    ----------
    labels : list of str
        Each profile's file (and key), for messages.
    names : list of str
        The text an id is searched in (the file's stem, or the key).
    pose_ids : tuple of str or None
        The poses' ids; None: the poses are numbered (1..N, or 0..N-1 when the names are).
    n_poses : int
    pose_file : str
    asked : Pairing
        ``--pair`` and ``--match``.

    Returns
    -------
    (list of int, list of str, str)
        Pose index per profile, the pose ids (generated when ``pose_ids`` is None), how.
    """
    mode, match = asked.mode, asked.match
    if match is None and mode != "order":
        for pattern, words in ((DEFAULT_MATCH, "last digits of the name"), (FIRST_DIGITS, "first digits of the name")):
            tokens = [_token(name, pattern) for name in names]
            ids = _pose_ids(pose_ids, tokens, n_poses)
            if _all_match(tokens, ids):
                return _by_id(labels, names, ids, tokens, pose_file), list(ids), f"by id in the file name ({words})"
    tokens = [_token(name, match or DEFAULT_MATCH) for name in names]
    ids = _pose_ids(pose_ids, tokens, n_poses)
    if mode == "order" or (mode == "auto" and match is None and all(t is None for t in tokens)):
        return _by_order(labels, ids, pose_file), list(ids), "by order (natural sort of the file names)"
    if mode == "auto" and match is None:
        lookup = _Ids(ids)
        matched = [bool(lookup.hits(t)) for t in tokens if t is not None]
        if not any(matched) and len(labels) == len(ids):
            return _by_order(labels, ids, pose_file), list(ids), "by order (the numbers in the names are not pose ids)"
    index = _by_id(labels, names, ids, tokens, pose_file)
    missing = sorted(set(range(len(ids))) - set(index))
    if missing:
        raise DatasetError(pose_file, f"pose {ids[missing[0]]!r} has no profile ({len(missing)} of {len(ids)} poses have "
                                      "none): add its file, or leave the pose out by deleting its row"
                                      + (" and giving the poses an id column (the numbers in the file names), since "
                                         "without ids the poses are numbered in order and the rest would shift"
                                         if pose_ids is None else "") + " (--pair order only pairs equal counts)")
    how = f"--match {match!r}" if match else "last digits of the name"
    return index, list(ids), f"by id in the file name ({how})"


FIRST_DIGITS = r"^\D*?(\d+)"


def _pose_ids(pose_ids, tokens, n_poses):
    """The poses' ids; without an id column 1..N, or 0..N-1 when the names' numbers start at 0."""
    if pose_ids is not None:
        return pose_ids
    zero = any(t is not None and t.isdigit() and _number(t) == "0" for t in tokens)
    return tuple(str(k + (0 if zero else 1)) for k in range(n_poses))


def _all_match(tokens, ids):
    """Every name has a number, each a different pose's, and every pose has one."""
    if not tokens or any(t is None for t in tokens) or len(tokens) != len(ids):
        return False
    lookup = _Ids(ids)
    hits = [lookup.hits(t) for t in tokens]
    return all(len(h) == 1 for h in hits) and len({h[0] for h in hits}) == len(ids)


def _by_order(labels, ids, pose_file):
    if len(labels) != len(ids):
        raise DatasetError(pose_file, f"{len(ids)} poses but {len(labels)} profiles ({labels[0]} ...): pair by id "
                                      "(a number in each file name, --match) or give as many of each")
    return list(range(len(ids)))
