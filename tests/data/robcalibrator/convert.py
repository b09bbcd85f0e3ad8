"""Convert RobCalibrator's sphere scans to handeye datasets (numpy + the standard library only).

Source: https://github.com/GilbertPan97/RobCalibrator (MIT, see README.md here), folder
``data/ScanData`` at commit efb60b8031ec534ebbd266664bf56abb94ebf7b8. Usage::

    python convert.py RobCalibrator/data/ScanData [OUT]      # OUT defaults to this file's folder

writes one handeye dataset folder per entry of ``DATASETS`` (``measurements.csv``, ``setup.toml``,
``profiles/*.csv``) and ``reference.json`` (RobCalibrator's own solution, converted to handeye's
sensor frame). What is read, and how it is turned into handeye's format:

poses
    FANUC x, y, z, w, p, r (mm, deg; RobCalibrator's ``XYZWPRVecToHTM`` is Rz(r) Ry(p) Rx(w)),
    from the JSON ``RobPoses`` of a ``.rob`` file or the whitespace-separated ``robpose.txt``;
    copied unchanged (``[robot] convention = "fanuc"``).
profiles
    OpenCV FileStorage YAML, ``scan_line: [x0, y0, z0, x1, ...]`` (cv::Point3f, y = 0, ``.Nan`` where
    the sensor saw nothing), or an ``!!opencv-matrix`` with ``data``. The file's z is a height: it
    grows towards the sensor (the sphere's visible cap lies above the fitted circle's centre in
    every file). handeye's z runs away from the sensor, so the profile is written as
    ``x = x_file, z = -z_file``; the frame stays right-handed with ``y = -y_file``.
sphere
    ``[sphere] diameter`` = 2 x ``CalibObj.Radius`` of the ``calibration.sec`` JSON; the centre is
    unknown (calibrate with ``--unknowns sensor+sphere``).
side
    ``CalibObj.SphCtrDirc`` (RobCalibrator's default ``+Y`` when absent) is the side of the laser
    plane in the file's y; handeye's y is the opposite, so ``-Y`` is ``side = 1`` and ``+Y`` is -1.
cleaning
    NaN points are dropped. Then RobCalibrator's own filter rule (``DataProc::SetDataFilter``:
    radius outlier removal, then DBSCAN's largest cluster), re-implemented: keep the points
    with at least ``MIN_NEIGHBOURS`` other points within ``NEIGHBOUR_MM``, then the largest
    group of them linked by steps shorter than ``LINK_MM``. It removes isolated speckle (the
    ball scans 7, 9 and 10 have hundreds of points scattered over the whole field of view) and
    nothing from a clean profile. ``ball-2023-05-raw`` (``"filter": False``) keeps every non-NaN
    point: the speckle is left for handeye's profile cleaning.
reference
    ``Solution.HTM`` of the ``calibration.sec`` is the sensor in the flange in the file's frame;
    in handeye's frame it is ``HTM @ diag(1, -1, -1, 1)``.
"""
from __future__ import annotations

import hashlib
import json
import pathlib
import re
import sys

import numpy as np

SOURCE_REPO = "https://github.com/GilbertPan97/RobCalibrator"
SOURCE_COMMIT = "efb60b8031ec534ebbd266664bf56abb94ebf7b8"

MIN_NEIGHBOURS = 4  # RobCalibrator: distances[minPts = 3] < 1.0, i.e. the 4th nearest other point
NEIGHBOUR_MM = 1.0
LINK_MM = 2.0  # RobCalibrator: DBSCAN eps = 2.0 mm (minPts 10; here every kept point may link)

#: handeye frame from the file's frame: x = x, y = -y, z = -z (a half turn about x).
FILE_FROM_HANDEYE = np.diag([1.0, -1.0, -1.0, 1.0])

DATASETS = {
    # the top-level scan: calibration.sec names this folder and RobPoses.rob, SphCtrDirc -Y
    "scan-2023-10-31": {"poses": "RobPoses.rob", "profiles": "p{k}.yml", "section": "calibration.sec"},
    # the same sensor, mount and 80 mm sphere the day before, with its own calibration.sec, which
    # predates SphCtrDirc: the side is the next day's -Y (+Y fails handeye's side check, exit 2,
    # and RobCalibrator's own solution of these data agrees with handeye's only under -Y)
    "scan-2023-10-30": {"poses": "tmp/10.30/RobPoses.rob", "profiles": "tmp/10.30/p{k}.yml",
                        "section": "tmp/10.30/calibration.sec", "SphCtrDirc": "-Y"},
    # another sensor (the "3C" line, AT C5 factory file in data/) on a 1-inch ball; its solution is
    # tmp/calibration.sec (Radius 12.7; its RobPoses, tmp/RobPoses.rob, are these poses)
    "ball-2023-05": {"poses": "ball/robpose.txt", "profiles": "ball/{k}_3C_line.yml", "section": "tmp/calibration.sec"},
    # the same ball scans with only their NaN points dropped (no filter): the speckle of scans 7, 9
    # and 10 left in, for handeye's own profile cleaning (tests/test_profile_clean.py)
    "ball-2023-05-raw": {"poses": "ball/robpose.txt", "profiles": "ball/{k}_3C_line.yml",
                         "section": "tmp/calibration.sec", "filter": False},
}


def git_blob_sha1(data):
    """The id git gives the file (``git ls-tree``), to check a copy against the source commit."""
    return hashlib.sha1(b"blob %d\0" % len(data) + data).hexdigest()


def _number(text):
    t = text.strip().lower()
    return float(t.replace(".nan", "nan").replace(".inf", "inf"))  # YAML's .Nan, .Inf, -.Inf


def read_filestorage(text, key):
    """The numbers under ``key`` of an OpenCV FileStorage YAML: a flow sequence ``key: [ ... ]``
    or an ``!!opencv-matrix`` (rows, cols, data); returned flat (matrices row-major) with the
    matrix shape, or None for a sequence."""
    m = re.search(rf"^{re.escape(key)}:\s*(!!opencv-matrix)?\s*(.*)", text, re.M | re.S)
    if m is None:
        raise ValueError(f"no {key!r} in the file")
    body = m.group(2)
    shape = None
    if m.group(1):
        rows = int(re.search(r"rows:\s*(\d+)", body).group(1))
        cols = int(re.search(r"cols:\s*(\d+)", body).group(1))
        shape = (rows, cols)
        body = body[body.index("data:") + len("data:"):]
    body = body[body.index("[") + 1:body.index("]")]
    values = np.array([_number(v) for v in body.replace("\n", " ").split(",") if v.strip()])
    return values, shape


def read_profile(path):
    """Points (K, 3) of a RobCalibrator scan line (file frame, mm), NaN rows included."""
    values, shape = read_filestorage(pathlib.Path(path).read_text(), "scan_line")
    return values.reshape(-1, 3) if shape is None else values.reshape(shape[0], -1)[:, :3]


def read_poses(path):
    """FANUC x, y, z, w, p, r rows (N, 6) of a ``.rob`` JSON or a whitespace table, and the text as read."""
    text = pathlib.Path(path).read_text()
    if text.lstrip().startswith("{"):
        poses = json.loads(text)["RobPoses"]
    else:
        poses = [[float(v) for v in line.split()] for line in text.splitlines() if line.strip()]
    poses = np.array(poses, dtype=float)
    if poses.ndim != 2 or poses.shape[1] != 6:
        raise ValueError(f"{path}: expected rows of x, y, z, w, p, r, got shape {poses.shape}")
    return poses


def clean(points):
    """Drop NaN rows, isolated points and every group but the largest (the module's rule).
    Returns (kept (K, 3), number of non-NaN points)."""
    pts = points[~np.isnan(points).any(axis=1)]
    valid = len(pts)
    if valid == 0:
        return pts, 0
    d = np.sqrt(((pts[:, None, [0, 2]] - pts[None, :, [0, 2]]) ** 2).sum(-1))
    near = (d < NEIGHBOUR_MM).sum(1) - 1  # other points within NEIGHBOUR_MM
    pts, d = pts[near >= MIN_NEIGHBOURS], d[np.ix_(near >= MIN_NEIGHBOURS, near >= MIN_NEIGHBOURS)]
    if len(pts) == 0:
        return pts, valid
    link = d < LINK_MM
    label = np.full(len(pts), -1)
    for seed in range(len(pts)):
        if label[seed] >= 0:
            continue
        label[seed] = seed
        frontier = np.zeros(len(pts), bool)
        frontier[seed] = True
        while frontier.any():
            reach = link[frontier].any(axis=0) & (label < 0)
            label[reach] = seed
            frontier = reach
    biggest = np.bincount(label).argmax()
    return pts[label == biggest], valid


def raw(points):
    """Drop only the NaN rows (a dataset left for handeye's own cleaning). Returns (kept, valid)."""
    pts = points[~np.isnan(points).any(axis=1)]
    return pts, len(pts)


def side_from(section, given=None):
    """handeye's ``[profile] side`` from ``SphCtrDirc`` (file's y; handeye's y is its opposite)."""
    dirc = given or section.get("CalibObj", {}).get("SphCtrDirc", "+Y")  # DataProc::CalcSphereCtrs' default
    return {"-Y": 1, "+Y": -1}[dirc], dirc


def convert(src, out, name, spec):
    src, folder = pathlib.Path(src), pathlib.Path(out) / name
    (folder / "profiles").mkdir(parents=True, exist_ok=True)
    sources = {}

    def source(rel):
        data = (src / rel).read_bytes()
        sources[f"data/ScanData/{rel}"] = git_blob_sha1(data)
        return src / rel

    poses = read_poses(source(spec["poses"]))
    section = json.loads(source(spec["section"]).read_text())
    radius = float(section["CalibObj"]["Radius"])
    side, dirc = side_from(section, spec.get("SphCtrDirc"))
    rows, kept = ["id,x,y,z,w,p,r,xs,ys,zs,profile"], {}
    for k, pose in enumerate(poses, start=1):
        rel = spec["profiles"].format(k=k)
        pts, valid = clean(read_profile(source(rel))) if spec.get("filter", True) else raw(read_profile(source(rel)))
        ident = pathlib.Path(rel).stem
        kept[ident] = {"points": int(valid), "kept": len(pts)}
        lines = "".join(f"{x:.3f},{-z:.4f}\n" for x, z in zip(pts[:, 0], pts[:, 2]))
        (folder / "profiles" / f"{ident}.csv").write_text("x,z\n" + lines)
        rows.append(f"{ident}," + ",".join(f"{v:.3f}" for v in pose) + f",,,,profiles/{ident}.csv")
    (folder / "measurements.csv").write_text("\n".join(rows) + "\n")
    (folder / "setup.toml").write_text(
        f"# converted by ../convert.py from {SOURCE_REPO} (commit {SOURCE_COMMIT[:7]}) {spec['section']}; see ../README.md\n"
        "[robot]\n"
        'convention = "fanuc"                # RobCalibrator: XYZWPRVecToHTM = Rz(r) Ry(p) Rx(w), mm and deg\n'
        "[sphere]\n"
        f"diameter = {2 * radius:g}                     # 2 x CalibObj.Radius; centre unknown: --unknowns sensor+sphere\n"
        "[profile]\n"
        f"side = {side}                            # SphCtrDirc {dirc} in the file's y; handeye's y = -y_file\n"
        + (f"# ({spec['SphCtrDirc']}: set in convert.py's DATASETS, not read from the section; see there)\n"
           if spec.get("SphCtrDirc") else ""))
    htm = np.array(section["Solution"]["HTM"], dtype=float)
    reference = {
        "source": SOURCE_REPO, "commit": SOURCE_COMMIT, "files_git_blob_sha1": sources,
        "sphere_radius_mm": radius, "SphCtrDirc": dirc, "side": side,
        "htm_file_frame": htm.tolist(), "xyzwpr_file_frame": section["Solution"]["xyzwpr"],
        "sensor2flange": (htm @ FILE_FROM_HANDEYE).tolist(),
        "saved": section.get("Description", {}).get("SaveTime"), "profiles": kept,
    }
    (folder / "reference.json").write_text(json.dumps(reference, indent=1) + "\n")
    return reference


def main(argv):
    if len(argv) not in (2, 3):
        sys.exit(__doc__)
    out = pathlib.Path(argv[2]) if len(argv) == 3 else pathlib.Path(__file__).resolve().parent
    for name, spec in DATASETS.items():
        ref = convert(argv[1], out, name, spec)
        dropped = {k: v["points"] - v["kept"] for k, v in ref["profiles"].items() if v["points"] != v["kept"]}
        print(f"{name}: {len(ref['profiles'])} poses, sphere R {ref['sphere_radius_mm']:g} mm, side {ref['side']}, "
              f"points dropped by the cleaning: {dropped or 'none'}")


if __name__ == "__main__":
    main(sys.argv)
