"""The report in a real browser: headless Chromium (tests/browser.py) opens it from disk, offline,
with no console error; the 3-D view is drawn on a WebGL canvas, the table has a row per sample, a
click on a heading sorts it, a click on a row picks the sample in the view, the slider moves the
residuals, and a screenshot is saved.

Needs Debian's chromium and chromium-driver (.ci/run installs them); a machine without them fails
here with that sentence rather than passing without having looked."""
from __future__ import annotations

import json
import pathlib
import sys

import pytest

import handeye

sys.path.insert(0, str(pathlib.Path(__file__).parent))
import browser  # noqa: E402


def _check(driver, path, n_samples, shot):
    from selenium.webdriver.common.by import By

    assert browser.open_report(driver, path) == "3d"
    assert browser.console_errors(driver) == []
    js = driver.execute_script
    assert js("return document.querySelectorAll('#cell3d canvas').length") >= 1
    assert js("var c = document.querySelector('#cell3d canvas'); return !!(c.getContext('webgl') || "
              "c.getContext('webgl2') || c.getContext('experimental-webgl')) || c.width > 0")
    rows = driver.find_elements(By.CSS_SELECTOR, "#residual-table tbody tr")
    assert len(rows) == n_samples
    cell = json.loads(js("return document.getElementById('handeye-cell').textContent"))
    # sort by |e| twice: descending, so the largest residual is on top
    head = driver.find_element(By.CSS_SELECTOR, "#residual-table th[data-key='norm']")
    head.click()
    head.click()
    assert head.get_attribute("aria-sort") == "descending"
    values = js("return Array.prototype.map.call(document.querySelectorAll('#residual-table tbody tr td:nth-child(5)'),"
                " function (td) { return parseFloat(td.getAttribute('data-v')); })")
    assert values == sorted(values, reverse=True)
    top = driver.find_element(By.CSS_SELECTOR, "#residual-table tbody tr")
    top.click()
    picked = int(top.get_attribute("data-i"))
    assert "picked" in top.get_attribute("class")
    assert cell["ids"][picked] in driver.find_element(By.ID, "picked").text
    sel = cell["traces"]["selected"]
    assert js(f"return document.getElementById('cell3d').data[{sel}].x.length") == 3  # flange, sensor, centre
    res = cell["traces"]["residuals"]
    before = js(f"return document.getElementById('cell3d').data[{res}].x.slice(0, 2)")
    js("var s = document.getElementById('residual-scale'); s.value = s.min; s.dispatchEvent(new Event('input'));")
    after = js(f"return document.getElementById('cell3d').data[{res}].x.slice(0, 2)")
    assert after[0] == pytest.approx(before[0]) and abs(after[1] - after[0]) < abs(before[1] - before[0])
    assert browser.console_errors(driver) == []
    driver.save_screenshot(str(shot))
    assert shot.stat().st_size > 10_000


@pytest.fixture(scope="module")
def driver():
    with browser.chromium() as d:
        yield d


def test_the_thesis_report_opens_in_chromium_without_a_console_error(driver, tmp_path):
    out = tmp_path / "thesis.html"
    res = handeye.calibrate("thesis-real", report=out, no_loo=True)
    _check(driver, out, len(res.residuals), tmp_path / "thesis.png")


@pytest.mark.slow(sibling="test_the_thesis_report_opens_in_chromium_without_a_console_error")
def test_reports_of_a_ur_cell_with_gross_errors_and_a_positioner_open_in_chromium(driver, tmp_path):
    ur, pos = tmp_path / "ur", tmp_path / "pos"
    handeye.simulate(out=ur, robot="ur10e", profiles=True, convention="ur", seed=3, effect=["outlier=x+45,y-22.5"])
    handeye.simulate(out=pos, sphere_mount="positioner", seed=2)
    for folder, unknowns, excluded in ((ur, "sensor+sphere", 2), (pos, "sensor+sphere+positioner", 0)):
        out = tmp_path / f"{folder.name}.html"
        written = handeye.report(folder, html=out, unknowns=unknowns)
        assert written.converged and written.interactive and written.excluded >= excluded
        _check(driver, out, written.samples, tmp_path / f"{folder.name}.png")
