"""The browser lab: the page writes the netlist analogy writes, runs it offline in ngspice compiled to
WebAssembly, and its exact solution is analogy's; moving a slider changes all three together."""

import re
from pathlib import Path

import numpy as np
import pytest

import analogy
from analogy.errors import InputError
from analogy.scenes.lab_page import engine_module, write_lab
from analogy.solvers.exact import solve_exact
from analogy.solvers.transient import netlist

ROOT = Path(__file__).resolve().parents[1]
ENGINE = ROOT / ".engines/wasm/node_modules/eecircuit-engine/dist/eecircuit-engine.mjs"
needs_engine = pytest.mark.skipif(not ENGINE.is_file(), reason="the WebAssembly ngspice (npm eecircuit-engine) is "
                                  "not installed: bash setup.sh test installs it where npm exists")
#: An element or source line: its name and its value, the last field.
LINE = re.compile(r"^([CRLI][0-9_]+) .* ([-+0-9.eE]+)$")


def _values(text: str) -> dict[str, float]:
    return {m.group(1): float(m.group(2)) for m in map(LINE.match, text.splitlines()) if m}


def _analysis(text: str) -> list[str]:
    return [ln for ln in text.splitlines() if ln.startswith((".ic", ".options", ".tran", ".save"))]


def _same_circuit(page: str, written: str, analysis: str | None = None) -> None:
    """The same parts with the same values (to rounding of T⁻ᵀ·M·T⁻¹, a few ε), and the analysis lines
    of *analysis* (default *written*'s): the page keeps those analogy chose for the scene as given."""
    a, b = _values(page), _values(written)
    assert set(a) == set(b), (sorted(a), sorted(b))
    for name, value in b.items():
        assert a[name] == pytest.approx(value, rel=64 * np.finfo(float).eps), name
    assert _analysis(page) == _analysis(analysis or written)


def _exact_rates(scene, times) -> np.ndarray:
    system = scene.system()
    return solve_exact(system, np.asarray(times)).rates


@needs_engine
def test_the_lab_runs_offline_writes_analogys_netlist_and_keeps_the_bound_as_sliders_move(tmp_path):
    sync_api = pytest.importorskip("playwright.sync_api")
    scene = analogy.scene("default")
    page_path = write_lab(scene, tmp_path, ENGINE)
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=["--no-sandbox"])
        page = browser.new_page()
        problems, requests = [], []
        page.on("console", lambda m: problems.append(m.text) if m.type in ("error", "warning") else None)
        page.on("pageerror", lambda e: problems.append(str(e)))
        page.on("request", lambda r: requests.append(r.url))
        page.goto(page_path.as_uri())
        page.wait_for_function("window.lab !== undefined && window.lab.runs >= 1", timeout=120_000)
        first = page.evaluate("window.lab")
        # nothing fetched but the page and the engine it holds
        assert all(u == page_path.as_uri() or u.startswith("blob:") for u in requests), requests
        _same_circuit(first["netlist"], netlist(scene.system(), scene.settings, printing=False))
        # its exact solution is analogy's, to the rounding of a matrix exponential (1e-12 of the peak)
        exact = np.array(first["exact"])
        ours = _exact_rates(scene, first["times"])
        assert np.max(np.abs(exact - ours)) <= 1e-12 * np.max(np.abs(ours))
        assert max(first["errors"]) <= scene.settings.bound
        # a heavier forearm at another elbow angle: the page re-writes, re-runs and re-solves
        page.evaluate("""() => {
            for (const input of document.querySelectorAll("input[type=range]")) {
                const label = input.previousSibling.textContent;
                if (label.startsWith("q2")) input.value = 700;
                if (label.startsWith("d2")) input.value = 650;
                input.dispatchEvent(new Event("input"));
            }
        }""")
        page.wait_for_function("window.lab.runs >= 2 && window.lab.p.d2 !== 1.0 && window.lab.q[1] !== 0.3",
                               timeout=60_000)
        page.wait_for_timeout(500)                   # any run still queued by the moves
        moved = page.evaluate("window.lab")
        browser.close()
    assert problems == []
    other = scene.replace(q=tuple(moved["q"]), parameters={**scene.parameter_values, **moved["p"]})
    _same_circuit(moved["netlist"], netlist(other.system(), scene.settings, printing=False), first["netlist"])
    ours = _exact_rates(other, moved["times"])
    assert np.max(np.abs(np.array(moved["exact"]) - ours)) <= 1e-12 * np.max(np.abs(ours))
    # the page's own verdict is SPICE against that exact solution, per joint over its own peak
    spice = np.array(moved["spice"])
    own = np.max(np.abs(spice - ours), axis=0) / np.max(np.abs(ours), axis=0)
    assert np.allclose(own, moved["errors"], rtol=1e-6)


def test_the_lab_refuses_what_its_page_cannot_vary_in_one_sentence():
    with pytest.raises(InputError, match="linear circuit"):
        write_lab(analogy.scene("default").replace(dynamics="nonlinear"), "unused", ENGINE)
    with pytest.raises(InputError, match="step from t = 0"):
        write_lab(analogy.scene("default").replace(forces=("sine(0, 1, 1)", 0.0)), "unused", ENGINE)
    with pytest.raises(InputError, match="no static load"):
        write_lab(analogy.scene("serial2").replace(q=(0.3, 0.2), parameters={"g": 9.81}), "unused", ENGINE)
    with pytest.raises(InputError, match="eecircuit-engine"):
        engine_module("/nonexistent/eecircuit-engine.mjs")
