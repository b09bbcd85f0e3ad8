"""``handeye dataset new``: a dataset folder assembled from loose files (issue 29).

A cell's data rarely arrive as a handeye dataset: the robot's poses are a CSV, a text dump or a
JSON export, the profiles an OpenCV FileStorage file, a NumPy array, a PLY or PCD cloud per pose,
or everything is in a ROS 2 bag. :func:`handeye.app.ingest.command.new_dataset` reads them (the
format told by each file's content, not its extension), checks them, pairs poses with profiles
and writes ``measurements.csv``, ``setup.toml``, ``profiles/*.csv`` and ``PROVENANCE.toml``
(:mod:`handeye.model.datasets.dataset` documents the format) atomically.

Modules: :mod:`~handeye.app.ingest.request` (the options, checked in one place before anything is
read), :mod:`~handeye.app.ingest.tables` (text and JSON tables), :mod:`~handeye.app.ingest.poses`
(pose columns, units, plausibility), :mod:`~handeye.app.ingest.controllers` (the robot controller's
own files: FANUC ``.ls``, KUKA ``.src``/``.dat``, ABB ``.mod``, URScript, UR RTDE logs, read by
:mod:`~handeye.app.ingest.controller_fanuc_kuka` and :mod:`~handeye.app.ingest.controller_abb_ur`
with :mod:`~handeye.app.ingest.controller_common`), :mod:`~handeye.app.ingest.opencv_storage` (FileStorage
YAML/XML/JSON), :mod:`~handeye.app.ingest.clouds` (CSV/TXT, .npy/.npz, PLY, PCD),
:mod:`~handeye.app.ingest.plane` (NaN rows, the laser plane's axes), :mod:`~handeye.app.ingest.sources`
(profiles read and mapped), :mod:`~handeye.app.ingest.pairing`,
:mod:`~handeye.app.ingest.rosbag` (ROS 2 bags, optional ``rosbags``), :mod:`~handeye.app.ingest.writer`
and :mod:`~handeye.app.ingest.command` (the command and its result).
"""
