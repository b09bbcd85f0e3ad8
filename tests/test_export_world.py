"""``handeye export`` of a sensor fixed in the cell (``sensor_mount "world"``): the sensor frame
in the robot base written as each consumer's base / user frame, and the flange export unchanged.

The parsers here rebuild the 4x4 sensor2base from each format's base-frame syntax with scipy's
Rotation and xml.etree, never with handeye's conventions; they refuse the tool syntax.
"""
import json
import pathlib
import re
import shutil
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import handeye
from handeye.app.command import cli
from handeye.app.common.errors import RequestError
from handeye.app.outputs import formats as export
from handeye.app.outputs import saved

TOL_MM, TOL_DEG = 1e-6, 1e-6
DATA = pathlib.Path(__file__).resolve().parent / "data" / "export"
TEXT_FORMATS = [f for f in export.FORMATS if f != "json"]


# ---------------------------------------------------------------- an independent reading of the base frames
def _numbers(text):
    return [float(v) for v in re.findall(r"[-+]?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?", text)]


def _transform(rot, trans_mm):
    t = np.eye(4)
    t[:3, :3] = rot.as_matrix()
    t[:3, 3] = trans_mm
    return t


def _code(text):
    return "\n".join(line for line in text.splitlines() if not line.lstrip().startswith(("#", ";", "!")))


def parse_base(fmt, text, parent="base_link", child="sensor"):
    """The 4x4 sensor2base (mm) a base-frame export describes; AssertionError on tool syntax."""
    body = _code(text)
    assert not re.search(r"set_tcp|TOOL_DATA|tooldata|UTOOL", body), body
    if fmt == "ur":
        v = _numbers(re.fullmatch(rf"global {child}_frame = p\[(.*)\]", body.strip()).group(1))
        return _transform(Rotation.from_rotvec(v[3:]), np.array(v[:3]) * 1000)
    if fmt == "ros2":
        opt = dict(re.findall(r"--([\w-]+) (\S+)", body))
        assert (opt["frame-id"], opt["child-frame-id"]) == (parent, child)
        q = [float(opt[k]) for k in ("qx", "qy", "qz", "qw")]
        return _transform(Rotation.from_quat(q), np.array([float(opt[k]) for k in "xyz"]) * 1000)
    if fmt == "urdf":
        joint = ET.fromstring(text[text.index("<joint"):])
        assert joint.get("type") == "fixed" and joint.find("parent").get("link") == parent
        assert joint.find("child").get("link") == child
        origin = joint.find("origin")
        xyz, rpy = ([float(v) for v in origin.get(k).split()] for k in ("xyz", "rpy"))
        return _transform(Rotation.from_euler("xyz", rpy), np.array(xyz) * 1000)  # extrinsic x, y, z
    if fmt == "kuka":
        inner = re.search(r"^BASE_DATA\[\d+\]=\{(.*?)\}$", body, re.M).group(1)
        frame = {k: float(v) for k, v in re.findall(r"([XYZABC]) ([-+\d.eE]+)", inner)}
        return _transform(Rotation.from_euler("ZYX", [frame[k] for k in "ABC"], degrees=True),
                          [frame[k] for k in "XYZ"])
    if fmt == "abb":
        m = re.fullmatch(r'PERS wobjdata (\w+) := \[FALSE, TRUE, "", \[\[(.*?)\], \[(.*?)\]\], '
                         r'\[\[0, 0, 0\], \[1, 0, 0, 0\]\]\];', body.strip())
        pos, q = _numbers(m.group(2)), _numbers(m.group(3))
        return _transform(Rotation.from_quat([q[1], q[2], q[3], q[0]]), pos)
    if fmt == "fanuc":
        register = re.search(r"UFRAME\[\d+\]=PR\[(\d+)\] ;", body).group(1)
        v = {int(k): float(x) for k, x in re.findall(rf"PR\[{register},(\d)\]=\(?([-+\d.eE]+)\)?", body)}
        return _transform(Rotation.from_euler("xyz", [v[4], v[5], v[6]], degrees=True), [v[1], v[2], v[3]])
    if fmt == "matrix":
        assert "sensor -> base" in text
        return np.array([_numbers(line) for line in body.strip().splitlines()])
    doc = json.loads(text)
    assert (doc["sensor_mount"], doc["parent"], doc["child"]) == ("world", parent, child)
    assert doc["calibration"]["sensor_mount"] == "world"
    return np.array(doc["sensor_matrix"])


def _close(a, b):
    dt = float(np.linalg.norm(a[:3, 3] - b[:3, 3]))
    dr = float(np.degrees(Rotation.from_matrix(a[:3, :3].T @ b[:3, :3]).magnitude()))
    return dt, dr


# ---------------------------------------------------------------- calibrations
def _world(m, sd=(0.1, 0.2, 0.3, 1e-3, 2e-3, 3e-3)):
    return saved.Calibration(np.asarray(m, float), np.diag(np.square(sd)), "test", sensor_mount="world")


def _edited(tmp_path, name="world.json", **changes):
    """The thesis calibration's saved JSON (sensor on the flange) with keys set as given."""
    doc = json.loads((DATA / "thesis-real.json").read_text())
    doc.update(changes)
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


HARD = {  # cell-scale poses and each format's singularity
    "sensor above the cell, looking down": _transform(Rotation.from_euler("xyz", [180, 0, 37], degrees=True),
                                                      [1450.0, -620.5, 2100.25]),
    "KUKA B=+90": _transform(Rotation.from_euler("ZYX", [33, 90, -12], degrees=True), [10, -20, 30]),
    "KUKA B=-90": _transform(Rotation.from_euler("ZYX", [180, -90, 0], degrees=True), [-800, 900, 5]),
    "UR half turn": _transform(Rotation.from_rotvec(np.pi * np.array([1, 0, 1]) / np.sqrt(2)), [1, 2, 3]),
    "quaternion w=0": _transform(Rotation.from_quat([1, 0, 0, 0]), [5, 6, 7]),
    "identity": np.eye(4),
}


@pytest.mark.parametrize("fmt", export.FORMATS)
def test_every_base_frame_reads_back_to_sensor2base(fmt):
    rng = np.random.default_rng(21)
    cases = dict(HARD)
    cases.update({f"random {k}": _transform(Rotation.random(random_state=rng), rng.uniform(-3000, 3000, 3))
                  for k in range(40)})
    for case, m in cases.items():
        dt, dr = _close(parse_base(fmt, export.text(_world(m), fmt)), m)
        assert dt <= TOL_MM and dr <= TOL_DEG, (case, fmt, dt, dr)


@pytest.mark.parametrize("fmt", export.FORMATS)
def test_a_world_calibration_file_exports_base_frames(fmt, tmp_path, capsys):
    path = _edited(tmp_path, sensor_mount="world")
    matrix = np.array(json.loads(path.read_text())["sensor_matrix"])
    assert cli.main(["export", str(path), "--format", fmt]) == 0
    text = capsys.readouterr().out
    dt, dr = _close(parse_base(fmt, text), matrix)
    assert dt <= TOL_MM and dr <= TOL_DEG, (fmt, dt, dr)
    if fmt == "fanuc":  # a TP comment holds 32 characters
        assert "! handeye: sensor fixed in cell ;" in text
    elif fmt != "json":
        assert "in the robot base, fixed in the cell" in text and "along the base's x, y, z" in text
    named = handeye.export(path, format=fmt, parent="world", child="laser", base=4, register=42).text
    dt, dr = _close(parse_base(fmt, named, parent="world", child="laser"), matrix)
    assert dt <= TOL_MM and dr <= TOL_DEG, (fmt, dt, dr)


def test_the_base_frame_syntax_of_each_controller(tmp_path):
    path = _edited(tmp_path, sensor_mount="world")
    out = {fmt: handeye.export(path, format=fmt, child="laser", base=5, register=42).text for fmt in TEXT_FORMATS}
    assert re.search(r"^BASE_DATA\[5\]=\{X [-\d.]+,Y [-\d.]+,Z [-\d.]+,A [-\d.]+,B [-\d.]+,C [-\d.]+\}$", out["kuka"],
                     re.M) and 'BASE_NAME[5,]="laser"' in out["kuka"]
    assert re.search(r'^PERS wobjdata wobj_laser := \[FALSE, TRUE, "", \[\[', out["abb"], re.M)
    assert "/PROG HANDEYE_UFRAME5" in out["fanuc"] and re.search(r"^ +\d+:  UFRAME\[5\]=PR\[42\] ;$", out["fanuc"], re.M)
    assert re.search(r"^global laser_frame = p\[", out["ur"], re.M) and "pose_trans(laser_frame" in out["ur"]
    assert "--frame-id base_link --child-frame-id laser" in out["ros2"]
    assert '<parent link="base_link"/>' in out["urdf"] and 'name="base_link_to_laser"' in out["urdf"]
    assert not re.search(r"set_tcp|TOOL_DATA|tooldata|UTOOL", _code("\n".join(out.values())))


@pytest.mark.parametrize("value", ["ceiling", "World", "", 3, None, ["world"]])
def test_an_unknown_mount_in_the_file_is_one_line_naming_the_key(value, tmp_path, capsys):
    path = _edited(tmp_path, sensor_mount=value)
    assert cli.main(["export", str(path), "--format", "ur"]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert captured.out == "" and "\n" not in err and "'sensor_mount'" in err and str(path) in err, err
    with pytest.raises(saved.CalibrationFileError, match="sensor_mount"):
        saved.load(path)


def test_a_file_without_the_key_and_one_saying_flange_are_on_the_flange(tmp_path):
    old = saved.load(DATA / "thesis-real.json")
    new = saved.load(_edited(tmp_path, sensor_mount="flange"))
    assert old.sensor_mount == new.sensor_mount == "flange" and old.frame == "flange"
    assert np.array_equal(old.sensor_matrix, new.sensor2flange)
    world = saved.load(_edited(tmp_path, sensor_mount="world"))
    assert world.sensor_mount == "world" and world.frame == "base"
    assert np.array_equal(world.sensor_matrix, old.sensor_matrix)


def _golden_texts(tmp_path):
    golden = json.loads((DATA / "flange-golden.json").read_text())
    path = tmp_path / "cal.json"
    shutil.copy(DATA / "thesis-real.json", path)
    for key, expected in golden["texts"].items():
        fmt, variant = key.split("|")
        options = dict(golden["variants"][variant])
        yield path, fmt, options, expected


def _is_comment(fmt, line):
    if fmt == "urdf":  # inside the header's <!-- ... --> block
        return line.startswith("  ") and not line.lstrip().startswith("<")
    return line.lstrip().startswith(("#", ";", "!"))


def assert_before_plus_verdict(fmt, text, expected):
    """``text`` is ``expected`` byte for byte, line for line in order, plus the verdict's comment lines
    (the status and the failed checks, issue 39) and nothing else; FANUC's TP line numbers aside
    (the verdict's comment lines number among the program's). JSON: the same object plus ``verdict``."""
    if fmt == "json":
        got = json.loads(text)
        assert got.pop("verdict")[0].startswith("verdict: ") and got == json.loads(expected)
        return
    def unnumbered(t):
        return [re.sub(r"^\s*\d+:  ", "", line) for line in t.splitlines()]
    got, want, at, kept = unnumbered(text), unnumbered(expected), 0, []
    for line in want:
        while at < len(got) and got[at] != line:
            at += 1
        assert at < len(got), (fmt, line, text)
        kept.append(at)
        at += 1
    extra = [line for k, line in enumerate(got) if k not in kept]
    assert extra and all(_is_comment(fmt, line) for line in extra), (fmt, extra)
    assert any("verdict: " in line for line in extra), (fmt, extra)
    assert text.endswith("\n") and text.count("\n") == len(got)


def test_flange_export_is_byte_identical_to_before(tmp_path):
    """Every format and option set, through the API and the CLI, as the code before wrote it, with
    the verdict's comment lines added (:func:`assert_before_plus_verdict`)."""
    count = 0
    for path, fmt, options, expected in _golden_texts(tmp_path):
        calibration = None if "sensor_pose" in options else path
        text = handeye.export(calibration, format=fmt, **options).text.replace(str(path), "<CAL>")
        assert_before_plus_verdict(fmt, text, expected)
        explicit = handeye.export(calibration, format=fmt, sensor_mount="flange", **options).text
        assert explicit.replace(str(path), "<CAL>") == text, (fmt, options)
        count += 1
    assert count == 3 * len(export.FORMATS)


def test_flange_export_through_the_cli_is_byte_identical(tmp_path, capsys):
    for path, fmt, options, expected in _golden_texts(tmp_path):
        args = ["export", "--format", fmt]
        if "sensor_pose" in options:
            args += ["--sensor-pose", options["sensor_pose"], "--convention", options["convention"]]
        else:
            args.append(str(path))
        for key in ("parent", "child", "tool", "register"):
            if key in options:
                args += [f"--{key}", str(options[key])]
        assert cli.main(args) == 0
        assert_before_plus_verdict(fmt, capsys.readouterr().out.replace(str(path), "<CAL>"), expected)


@pytest.mark.parametrize("fmt", export.FORMATS)
def test_a_pose_typed_in_with_sensor_mount_world_is_a_base_frame(fmt, capsys):
    pose = "1450,-620.5,2100.25,37,0,180"
    assert cli.main(["export", "--sensor-pose", pose, "--convention", "kuka", "--sensor-mount", "world",
                     "--format", fmt]) == 0
    expected = _transform(Rotation.from_euler("ZYX", [37, 0, 180], degrees=True), [1450, -620.5, 2100.25])
    dt, dr = _close(parse_base(fmt, capsys.readouterr().out), expected)
    assert dt <= TOL_MM and dr <= TOL_DEG, (fmt, dt, dr)


def test_a_4x4_given_with_sensor_mount_world_is_a_base_frame():
    m = HARD["sensor above the cell, looking down"]
    dt, dr = _close(parse_base("kuka", handeye.export(m, format="kuka", sensor_mount="world").text), m)
    assert dt <= TOL_MM and dr <= TOL_DEG


def test_options_that_do_not_fit_the_mount_are_refused(tmp_path, capsys):
    world, flange = _edited(tmp_path, sensor_mount="world"), DATA / "thesis-real.json"
    refused = [
        [str(world), "--format", "kuka", "--tool", "2"],          # a base is numbered with --base
        [str(flange), "--format", "kuka", "--base", "2"],         # a tool with --tool
        [str(world), "--format", "kuka", "--base", "33"],         # KUKA BASE_DATA 1..32
        [str(world), "--format", "fanuc", "--base", "10"],        # FANUC UFRAME 1..9
        [str(world), "--format", "abb", "--child", "a" * 28],     # wobj_ + 28 > 32 characters
        [str(world), "--format", "ur", "--child", "laser-1"],     # not a URScript identifier
        [str(flange), "--sensor-mount", "world"],                 # the file says where its sensor is
        [str(world), "--sensor-mount", "flange"],
    ]
    for args in refused:
        assert cli.main(["export"] + args) == 2, args
        assert "error" in capsys.readouterr().err, args
    with pytest.raises(SystemExit) as exc:  # argparse: not a choice
        cli.main(["export", "--sensor-pose", "1,2,3,0,0,0", "--convention", "kuka", "--sensor-mount", "ceiling"])
    assert exc.value.code == 2
    capsys.readouterr()
    assert cli.main(["export", str(world), "--format", "kuka", "--base", "32"]) == 0
    assert "BASE_DATA[32]=" in capsys.readouterr().out
    with pytest.raises(RequestError, match="--sensor-mount 'ceiling'"):
        handeye.export(sensor_pose="1,2,3,0,0,0", convention="kuka", sensor_mount="ceiling")


def test_the_parent_default_follows_the_mount(tmp_path):
    world = _edited(tmp_path, sensor_mount="world")
    assert "--frame-id base_link " in handeye.export(world, format="ros2").text
    assert "--frame-id flange " in handeye.export(DATA / "thesis-real.json", format="ros2").text
    assert "--frame-id world " in handeye.export(world, format="ros2", parent="world").text
    assert json.loads(handeye.export(world).text)["parent"] == "base_link"
    assert "sensor_mount" not in json.loads(handeye.export(DATA / "thesis-real.json").text)


def test_cloud_and_validate_refuse_a_calibration_of_another_mount(tmp_path):
    """A sensor2base read as a sensor2flange (or the other way round) gives wrong numbers without a
    warning: validate and cloud refuse it, naming both mounts."""
    world = _edited(tmp_path, sensor_mount="world")
    with pytest.raises(RequestError, match="sensor mounted on the world.*mounts the sensor on the flange"):
        handeye.validate("thesis-sim", world)
