"""The HTML report: one self-contained page of a scene's run, checked in a real browser."""

import re
import shutil
import subprocess
import sys

import numpy as np
import pytest

import analogy
from analogy.scenes.report import scene_report

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
#: Flags for a root, offline, headless start: no sandbox (root), no GPU, no calls home.
CHROMIUM_FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                  "--disable-sync", "--no-first-run"]


def cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "analogy", *args], capture_output=True, text=True,
                          timeout=600, cwd=cwd)


@pytest.fixture(scope="module")
def default_report():
    return scene_report(analogy.scene("default"), frames=6)


@pytest.mark.ngspice
def test_a_report_holds_the_verdict_the_circuit_the_netlist_that_ran_and_the_key(default_report, tmp_path):
    page = default_report.html
    sc = default_report.scene
    assert "within the accurate preset's bound 1e-06 of its own peak, against exact" in page
    assert sc.key in page and default_report.comparison.caption in page
    # the circuit as SVG, the plot as PNG, the animation's frames as PNG; nothing fetched from outside
    assert page.count("data:image/svg+xml;base64,") == 2 and "data:image/png;base64," in page
    assert "http://" not in page and "https://" not in page
    # the netlist on the page is the one `analogy netlist` writes for the scene
    written = cli("netlist")
    assert written.returncode == 0 and default_report.netlist == written.stdout
    assert default_report.save(tmp_path / "r").read_text() == page


@pytest.mark.ngspice
def test_a_report_flags_the_output_past_its_bound_and_exits_3(tmp_path):
    # the 2-DOF arm released without damping from far up: chaotic (its motion parts from one
    # 1e-12 away by 1e-6 in 11 s, growing as e^(1.24 t)), so no solver follows it to 1e-3 for 12 s
    out = cli("report", "--dynamics", "nonlinear", "--param", "g=9.81", "--param", "b1=0", "--param", "b2=0",
              "--q", "2.5, 2", "--force", "0", "--force", "0", "--t-stop", "12", "--preset", "fast",
              "--no-animation", "-o", "r", cwd=tmp_path)
    assert out.returncode == 3, out.stderr
    flagged = re.search(r"spice error on (r[12]) ", out.stderr)
    assert flagged is not None, out.stderr
    page = (tmp_path / "r" / "index.html").read_text()
    assert "class='verdict broken'" in page and f"spice error on {flagged.group(1)} is" in page


def test_a_scene_file_and_scene_flags_together_are_refused(tmp_path):
    (tmp_path / "s.toml").write_text('[model]\nrobot = "serial2"\n[configuration]\nq = [0, 0.3]\n')
    out = cli("report", "s.toml", "--robot", "serial3", "-o", "r", cwd=tmp_path)
    assert out.returncode == 2 and "give a scene file or scene flags, not both: --robot" in out.stderr
    assert not (tmp_path / "r").exists()


def chromium_page(path, action=None):
    """Open *path* in headless Chromium: its images (alt, complete, width), its console and a screenshot."""
    sync_playwright = pytest.importorskip("playwright.sync_api", reason="playwright is installed by "
                                          "bash setup.sh test").sync_playwright
    if CHROMIUM is None:
        pytest.skip("Chromium is not installed (bash setup.sh test installs Debian's chromium)")
    shot = path.with_suffix(".png")
    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 900})
            console = []
            page.on("console", lambda m: console.append(f"{m.type}: {m.text}"))
            page.on("pageerror", lambda e: console.append(f"pageerror: {e}"))
            page.goto(path.as_uri())
            page.wait_for_load_state("load")
            images = page.evaluate("Array.from(document.images).map(i => [i.alt, i.complete, i.naturalWidth])")
            if action is not None:
                action(page)
            page.screenshot(path=str(shot), full_page=True)
        finally:
            browser.close()
    import matplotlib.image
    pixels = matplotlib.image.imread(shot)[..., :3]
    return images, console, pixels


def _inked(pixels) -> float:
    """Share of the pixels that are not (near) white."""
    return float(np.mean(np.any(pixels < 0.9, axis=-1)))


def _play(page):
    # the player runs: a click on play moves its slider off frame 0
    start = page.locator("input[type=range]").input_value()
    page.get_by_role("button", name="Play", exact=True).click()
    page.wait_for_function("(s) => document.querySelector('input[type=range]').value != s", arg=start,
                           timeout=30_000)


@pytest.mark.browser
@pytest.mark.ngspice
def test_the_report_opens_in_chromium_with_every_image_and_no_console_error(default_report, tmp_path):
    images, console, pixels = chromium_page(default_report.save(tmp_path / "report"), _play)
    assert console == []
    # circuit, mechanism, rates and errors, and the player's frame
    assert len(images) == 4 and all(complete and width > 0 for _, complete, width in images), images
    assert pixels.shape[0] > 2000 and _inked(pixels) > 0.03


@pytest.mark.browser
@pytest.mark.ngspice
def test_a_batch_report_opens_in_chromium_with_its_plots(tmp_path):
    from sweep_text import sweep_text
    (tmp_path / "arm.toml").write_text(sweep_text(40, group_size=20))
    assert cli("batch", "arm.toml", "-o", "s", "--no-progress", cwd=tmp_path).returncode == 0
    assert cli("batch", "report", "s", cwd=tmp_path).returncode == 0
    images, console, pixels = chromium_page(tmp_path / "s" / "_report" / "report.html")
    assert console == []
    assert [alt for alt, _, _ in images] == ["Error against each axis", "Error histogram"]
    assert all(complete and width > 0 for _, complete, width in images)
    assert _inked(pixels) > 0.03
