"""A real headless Chromium for the report's tests (selenium + Debian's chromium and chromium-driver,
which .ci/run installs), and the README's report screenshots.

    python tests/browser.py OUT_DIR     # the three README screenshots of `handeye report`

Chromium starts as the machine's probe starts it: no sandbox (root in CI), no GPU (WebGL in
software), no background networking (the machine's closed network refuses it, loudly).
"""
from __future__ import annotations

import contextlib
import pathlib
import shutil
import subprocess
import sys
import time

FLAGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--disable-dev-shm-usage")


def executables():
    """(chromium, chromedriver) paths, or None for what is missing."""
    return (shutil.which("chromium") or shutil.which("chromium-browser"), shutil.which("chromedriver"))


@contextlib.contextmanager
def chromium(width=1400, height=1000):
    """A selenium driver of headless Chromium that keeps the page's console (``console(driver)``)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    browser, driver_path = executables()
    if browser is None or driver_path is None:
        raise RuntimeError("headless Chromium is missing: apt-get install chromium chromium-driver (.ci/run does)")
    opts = webdriver.ChromeOptions()
    opts.binary_location = browser
    for flag in (*FLAGS, f"--window-size={width},{height}"):
        opts.add_argument(flag)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(driver_path), options=opts)
    try:
        yield driver
    finally:
        driver.quit()


def open_report(driver, path, timeout=60.0):
    """Load a report and wait until its script has run (``body[data-ready]``: '3d' or 'static')."""
    driver.get(pathlib.Path(path).resolve().as_uri())
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        ready = driver.execute_script("return document.body && document.body.getAttribute('data-ready')")
        if ready:
            return ready
        time.sleep(0.1)
    raise TimeoutError(f"{path}: the page's script did not finish in {timeout:g} s")


def console_errors(driver):
    """The console's errors (level SEVERE) since the last call; warnings (WebGL's software
    rendering says it stalls on ReadPixels) are not errors."""
    return [e for e in driver.get_log("browser") if e.get("level") == "SEVERE"]


def _reports(folder):
    """The three README cells: the thesis's, a simulated UR10e with two gross errors, one on a positioner."""
    run = [sys.executable, "-m", "handeye.app.command.cli"]
    sim = folder / "ur10e-sim"
    pos = folder / "positioner-sim"
    if not sim.exists():
        subprocess.run(run + ["simulate", "--out", str(sim), "--robot", "ur10e", "--profiles", "--convention", "ur",
                              "--seed", "3", "--effect", "outlier=x+45,y-22.5"], check=True, capture_output=True)
    if not pos.exists():
        subprocess.run(run + ["simulate", "--out", str(pos), "--sphere-mount", "positioner", "--seed", "2"], check=True,
                       capture_output=True)
    jobs = {"thesis-real": ["thesis-real", "--diagnose"], "ur10e": [str(sim), "--unknowns", "sensor+sphere"],
            "positioner": [str(pos), "--unknowns", "sensor+sphere+positioner"]}
    out = {}
    for name, args in jobs.items():
        html = folder / f"report_{name}.html"
        subprocess.run(run + ["report", *args, "--html", str(html)], check=True, capture_output=True)
        out[name] = html
    return out


def screenshots(folder):
    """Write each README report's page top and its 3-D cell as PNGs into ``folder``."""
    import tempfile

    from selenium.webdriver.common.by import By

    folder = pathlib.Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    with chromium(1400, 1000) as driver, tempfile.TemporaryDirectory() as work:
        for name, html in _reports(pathlib.Path(work)).items():
            open_report(driver, html)
            errors = console_errors(driver)
            if errors:
                raise RuntimeError(f"{html}: console errors {errors}")
            for part in ("verdict", "cell"):
                el = driver.find_element(By.ID, part)
                driver.execute_script("arguments[0].scrollIntoView()", el)
                time.sleep(0.5)
                path = folder / f"report_{name}_{part}.png"
                el.screenshot(str(path))
                written.append(path)
    return written


if __name__ == "__main__":
    for p in screenshots(sys.argv[1] if len(sys.argv) > 1 else "notebooks/figures"):
        sys.stdout.write(f"{p}\n")
