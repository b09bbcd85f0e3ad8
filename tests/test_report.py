"""The one-file HTML report (handeye report, calibrate --report): what it holds, checked without a
browser (tests/test_report_browser.py opens it in one).

The page is built from the calibration's JSON object; these tests hold it to that object (the
embedded copy is exactly ``calibrate --json``), to the chain (the drawn residuals are the result's,
for every mount), and to the CLI's rules (exit codes, one line on bad input, never over an input)."""
from __future__ import annotations

import html.parser
import json
import subprocess
import sys

import numpy as np
import pytest

import handeye
from handeye.app.command.cli import main
from handeye.app.present.web import cell as cell_mod
from handeye.app.present.web import page, parts, view


class _Scripts(html.parser.HTMLParser):
    """The page's JSON script elements by id, its table rows, its external references."""

    def __init__(self):
        super().__init__()
        self.json, self.rows, self.external, self._id, self.images, self.canvas_divs = {}, [], [], None, 0, 0

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "script" and a.get("type") == "application/json":
            self._id = a["id"]
        if tag == "script" and a.get("src") or tag == "link" and a.get("href"):
            self.external.append(a)
        if tag == "tr" and "data-id" in a:
            self.rows.append(a["data-id"])
        if tag == "img" and a.get("src", "").startswith("data:image/png;base64,"):
            self.images += 1
        if tag == "div" and a.get("id") == "cell3d":
            self.canvas_divs += 1

    def handle_data(self, data):
        if self._id:
            self.json[self._id] = self.json.get(self._id, "") + data

    def handle_endtag(self, tag):
        if tag == "script":
            self._id = None


def parse(path):
    p = _Scripts()
    p.feed(path.read_text(encoding="utf-8"))
    return p


@pytest.fixture(scope="module")
def thesis_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "thesis.html"
    result = handeye.calibrate("thesis-real", report=out)
    return result, out


def test_the_page_embeds_exactly_the_calibrate_json_object_and_one_row_per_sample(thesis_report):
    result, out = thesis_report
    p = parse(out)
    assert json.loads(p.json["handeye-result"]) == json.loads(result.to_json())
    assert p.rows == [r.id for r in result.residuals]  # one row per sample, named by its id, in the dataset's order
    assert not p.external  # one file: no script or style fetched from anywhere
    assert p.canvas_divs == 1 and p.images == 2  # the 3-D view; residuals against angles and correlation figures
    text = out.read_text(encoding="utf-8")
    for said in ("Verdict", "χ² test", "leave-one-out", "identifiability", "global check", "copy-matrix", "set_tcp",
                 "TOOL_DATA", "static_transform_publisher"):
        assert said in text


def test_the_drawn_residuals_are_the_results_for_every_mount(tmp_path):
    """Whole vectors, not only lengths: the cell's residual in the base is the result's residual
    vector, rotated into the base where the result's lives in another frame (a sensor fixed in the
    cell: the flange frame), and its sensor-frame column is that vector in the drawn sensor frame;
    the drawn sensor frame sits where the simulation put the sensor."""
    from handeye.model.chain import conventions
    from handeye.model.chain.mounts import table2base

    cases = {"seed": ([], "sensor"), "eth": (["--sensor-mount", "world", "--sphere-mount", "flange"], "sensor+sphere"),
             "pos": (["--sphere-mount", "positioner"], "sensor+sphere+positioner")}
    for name, (args, unknowns) in cases.items():
        folder = tmp_path / name
        handeye.simulate(out=folder, seed=5, **_kw(args))
        res = handeye.calibrate(folder, unknowns=unknowns, no_loo=True)
        assert res.converged, (name, res.message)
        data = handeye.load_dataset(folder)
        geo = cell_mod.cell_geometry(res.to_dict(), data)
        vectors = np.array([r.vector for r in res.residuals])
        if name == "eth":  # the result's residual is in the flange frame there (model/chain/mounts.py)
            vectors = np.einsum("nij,nj->ni", data.flange2base()[:, :3, :3], vectors)
        if name == "pos":  # ... and in the table frame, at the calibrated axes
            table = table2base(cell_mod.result_mounts(res.to_dict(), data).axes, data.axis_angles)
            vectors = np.einsum("nij,nj->ni", table[:, :3, :3], vectors)
        np.testing.assert_allclose(geo.residual_base, vectors, atol=1e-6, err_msg=name)
        rot = geo.sensor2base[:, :3, :3]
        np.testing.assert_allclose(np.einsum("nij,ni->nj", rot, geo.residual_base), geo.residual_sensor, atol=1e-9)
        truth = conventions.transform_from(data.convention, data.truth["sensor_pose"])
        expected = truth if name == "eth" else data.flange2base() @ truth
        assert np.abs(geo.sensor2base[:, :3, 3] - np.reshape(expected, (-1, 4, 4))[:, :3, 3]).max() < 0.5, name
        assert geo.used.all() and len(geo.fans) == len(data)


def _kw(args):
    return {"sensor_mount": args[1], "sphere_mount": args[3]} if len(args) == 4 else (
        {"sphere_mount": args[1]} if args else {})


def test_excluded_samples_are_drawn_near_with_their_true_length_in_the_table(thesis_report):
    result, out = thesis_report
    data = handeye.load_dataset("thesis-real")
    geo = cell_mod.cell_geometry(result.to_dict(), data)
    drawn = np.linalg.norm(view.capped_residuals(geo), axis=1)
    longest_used = np.linalg.norm(geo.residual_base[geo.used], axis=1).max()
    assert (~geo.used).sum() == len(result.excluded) > 0
    assert drawn.max() <= view.EXCLUDED_CAP * longest_used + 1e-9
    row = next(r for r in result.residuals if r.id == "x+22.5")  # the 2 m gross error
    assert row.norm > 1000 and f"data-v='{row.norm!r}'" in out.read_text(encoding="utf-8")


def test_a_saved_calibration_of_another_dataset_is_refused_naming_the_key(tmp_path):
    cal = tmp_path / "cal.json"
    handeye.calibrate("thesis-real", out=cal, no_loo=True)
    run = subprocess.run([sys.executable, "-m", "handeye.app.command.cli", "report", "thesis-sim", "--calibration", str(cal),
                          "--html", str(tmp_path / "r.html")], capture_output=True, text=True)
    assert run.returncode == 2 and "dataset_sha256" in run.stderr and "another dataset" in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1 and not (tmp_path / "r.html").exists()
    bare = tmp_path / "bare.json"
    bare.write_text(json.dumps({"sensor_matrix": np.eye(4).tolist()}))
    run = subprocess.run([sys.executable, "-m", "handeye.app.command.cli", "report", "thesis-real", "--calibration", str(bare),
                          "--html", str(tmp_path / "r.html")], capture_output=True, text=True)
    assert run.returncode == 2 and "not a whole calibration result" in run.stderr


def test_a_saved_calibration_reports_as_the_run_that_made_it(tmp_path):
    cal = tmp_path / "cal.json"
    res = handeye.calibrate("thesis-real", out=cal, no_loo=True)
    out = handeye.report("thesis-real", calibration=cal, html=tmp_path / "r.html")
    assert out.converged and out.source == str(cal) and out.samples == len(res.residuals)
    embedded = json.loads(parse(tmp_path / "r.html").json["handeye-result"])
    assert embedded["sensor_matrix"] == json.loads(cal.read_text())["sensor_matrix"]


def test_the_report_never_overwrites_an_input_and_scores_have_none(tmp_path):
    data = handeye.load_dataset("thesis-sim")
    target = data.path / "measurements.csv"
    with pytest.raises(handeye.InputError, match="--html"):
        handeye.report("thesis-sim", html=target)
    with pytest.raises(handeye.InputError, match="--report"):
        handeye.calibrate("thesis-sim", sensor_pose="0,0,100,0,0,0", report=tmp_path / "r.html")


def test_without_plotly_the_cell_is_a_picture(monkeypatch, tmp_path):
    monkeypatch.setattr(view, "have_plotly", lambda: False)
    res = handeye.calibrate("thesis-sim", no_loo=True)
    text = page.build(res.to_dict(), handeye.load_dataset("thesis-sim"))
    p = _Scripts()
    p.feed(text)
    assert p.canvas_divs == 0 and p.images == 3 and "plotly.js" not in text and "handeye[report]" in text
    assert json.loads(p.json["handeye-cell"])["traces"] is None


def test_embedded_json_survives_html_in_its_strings():
    text = json.dumps({"id": "</script><script>alert(1)</script>", "c": "<!-- x"})
    el = page.embedded_json("x", text)
    p = _Scripts()
    p.feed(el)
    assert json.loads(p.json["x"]) == json.loads(text)
    assert el.count("</script>") == 1


def test_the_report_command_prints_what_it_wrote_and_exits_as_the_calibration(tmp_path):
    run = subprocess.run([sys.executable, "-m", "handeye.app.command.cli", "report", "thesis-sim", "--html",
                          str(tmp_path / "r.html"), "--json"], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert out["converged"] and out["samples"] == len(handeye.load_dataset("thesis-sim"))
    assert out["size_bytes"] == (tmp_path / "r.html").stat().st_size


def test_a_fit_with_effects_says_the_view_draws_the_plain_chain(tmp_path):
    out = tmp_path / "eff.html"
    res = handeye.calibrate("thesis-real", effects="sensor_scale", no_loo=True, report=out)
    assert res.effects and "Effects calibrated (sensor_scale)" in out.read_text(encoding="utf-8")


def test_thousands_of_poses_draw_a_few_hundred_frames():
    some = view.drawn_poses(5000)
    assert len(some) == view.MAX_DRAWN_POSES and some[0] == 0 and some[-1] == 4999
    assert list(view.drawn_poses(7)) == list(range(7)) and len(view.drawn_poses(0)) == 0


def test_large_cells_draw_every_excluded_sample_and_used_ones_evenly_spaced(thesis_report, monkeypatch):
    """Above MAX_DRAWN_CENTRES samples the view draws that many centres and residuals (every excluded one), the
    page's script redraws the same ones (the payload's ``drawn``), and the page says so; the table keeps all."""
    result, _ = thesis_report
    geo = cell_mod.cell_geometry(result.to_dict(), handeye.load_dataset("thesis-real"))
    monkeypatch.setattr(view, "MAX_DRAWN_CENTRES", 10)
    drawn = view.drawn_samples(geo)
    used = np.flatnonzero(geo.used & drawn)
    assert drawn.sum() == 10 and drawn[~geo.used].all() and used[0] == np.flatnonzero(geo.used)[0]
    assert used[-1] == np.flatnonzero(geo.used)[-1]  # evenly spaced from the first used sample to the last
    html, payload = page.cell_section(geo, "t", True, result.to_dict())
    fig, traces, _ = view.figure(geo, "t")
    assert payload["drawn"] == drawn.tolist() and len(fig.data[traces["centres"]].x) == len(used)
    assert "Centres and residuals of 10 of the 31 samples" in html


def test_the_page_inlines_plotlys_gl3d_bundle_of_the_installed_version(thesis_report):
    """The 3-D view's JavaScript is plotly.js's own gl3d bundle (1.75 MB, not the 4.8 MB full one) where the
    installed plotly writes figures for its version, else that plotly's full bundle."""
    import plotly.offline

    text = thesis_report[1].read_text(encoding="utf-8")
    gl3d = plotly.offline.get_plotlyjs_version() == view.BUNDLE_VERSION
    assert ("plotly.js (gl3d - minified) v" + view.BUNDLE_VERSION in text) == gl3d
    assert (plotly.offline.get_plotlyjs()[:2000] in text) == (not gl3d)


def test_a_calibration_that_did_not_converge_offers_no_controller_code(tmp_path):
    """The page says it is no calibration at the top, and offers no snippet to paste (as export
    refuses it)."""
    res = handeye.calibrate("thesis-sim", no_loo=True).to_dict()
    res["converged"], res["message"] = False, "iteration limit reached"
    text = page.build(res, handeye.load_dataset("thesis-sim"))
    assert "Not a calibration" in text and "Not offered" in text
    assert "set_tcp" not in text and "TOOL_DATA" not in text


@pytest.mark.slow(sibling="test_a_fit_with_effects_says_the_view_draws_the_plain_chain")
def test_the_card_shows_calibrated_positioner_axes_and_effects(tmp_path):
    pos = tmp_path / "pos"
    handeye.simulate(out=pos, sphere_mount="positioner", seed=2)
    res = handeye.calibrate(pos, unknowns="sensor+sphere+positioner", no_loo=True)
    text = page.build(res.to_dict(), handeye.load_dataset(pos))
    assert "Positioner axes" in text and text.count("calibrated</td>") == len(res.positioner.axes)
    eff = handeye.calibrate("thesis-real", effects="sensor_scale", no_loo=True)
    text = page.build(eff.to_dict(), handeye.load_dataset("thesis-real"))
    assert "Effects calibrated with the pose" in text and f"{eff.effects[0].parameters['s']:.6g}" in text


def test_nearly_tied_unknowns_are_not_a_pass_and_the_headline_says_what_fails(thesis_report):
    """thesis-real: ty-wx and tz-wy correlate at -1.00; the residuals are 67x the stated noise."""
    result, out = thesis_report
    text = out.read_text(encoding="utf-8")
    assert "nearly tied" in text and "ty–wx" in text
    assert "check(s) fail: RMS against stated noise, χ² test" in text


def test_options_of_a_new_calibration_are_refused_with_a_saved_one(tmp_path):
    cal = tmp_path / "cal.json"
    handeye.calibrate("thesis-sim", out=cal, no_loo=True)
    with pytest.raises(handeye.InputError, match="--unknowns"):
        handeye.report("thesis-sim", calibration=cal, unknowns="sensor+sphere", html=tmp_path / "r.html")


def test_verdict_states_follow_the_result_not_the_layout():
    base = handeye.calibrate("thesis-sim", no_loo=True).to_dict()
    def state(result, title):
        html_ = parts.verdict_strip(result)
        box = html_.split(f"<div class='vt'>{title}</div>")[0].rsplit("<div class='verdict ", 1)[1]
        return box.split("'", 1)[0]
    assert state(base, "convergence") == "ok" and state(base, "global check") == "ok"
    assert state({**base, "global": {**base["global"], "reached": 0}}, "global check") == "fail"
    assert state({**base, "global": {**base["global"], "reached": 1, "starts": 2}}, "global check") == "warn"
    assert state({**base, "noise_test": {**base["noise_test"], "passed": False}}, "χ² test") == "fail"
    assert "Not a calibration" in parts.verdict_strip({**base, "converged": False})


def test_a_hand_broken_saved_file_is_named_never_a_traceback(tmp_path, capsys):
    """Through the command line's own entry (in this process: an exception it does not turn into
    one line and its code would fail the test as a traceback would)."""
    cal = tmp_path / "cal.json"
    handeye.calibrate("thesis-sim", out=cal, no_loo=True)
    doc = json.loads(cal.read_text())
    for key, value in (("sensor_matrix", [[1, 0, 0], [0, 1, 0]]), ("sphere_center", None),
                       ("noise_test", {"statistic": None, "passed": False}), ("dataset_sha256", None)):
        bad = tmp_path / f"bad_{key}.json"
        bad.write_text(json.dumps({**doc, key: value}))
        code = main(["report", "thesis-sim", "--calibration", str(bad), "--html", str(tmp_path / "r.html")])
        err = capsys.readouterr().err
        assert code in (0, 2) and "Traceback" not in err, (key, err)
        if code == 2:
            assert str(bad) in err and len(err.strip().splitlines()) == 1, key
