"""Shared fixtures; tests marked ``ngspice`` need the ngspice library and executable."""

import ctypes.util
import os
import shutil
import tempfile
from pathlib import Path

import pytest

# Compiled models go to a cache of the test run's own, never the user's.
os.environ.setdefault("ANALOGY_CACHE_DIR", tempfile.mkdtemp(prefix="analogy-test-cache-"))

HAVE_LIBRARY = bool(os.environ.get("NGSPICE_LIBRARY_PATH") or ctypes.util.find_library("ngspice"))
HAVE_EXECUTABLE = shutil.which("ngspice") is not None


def pytest_collection_modifyitems(config, items):
    # In CI ngspice is installed by setup.sh, so a missing ngspice there is a failure, not a skip.
    if os.environ.get("CI") or (HAVE_LIBRARY and HAVE_EXECUTABLE):
        return
    skip = pytest.mark.skip(reason="ngspice is not installed (run: bash setup.sh test)")
    for item in items:
        if "ngspice" in item.keywords:
            item.add_marker(skip)


@pytest.fixture(scope="session", autouse=True)
def contact_sheet_of_the_run(tmp_path_factory):
    """After the run: test-output/contact_sheet.png tiles every picture the tests wrote."""
    yield
    from contact_sheet import contact_sheet
    pngs = sorted(tmp_path_factory.getbasetemp().rglob("*.png"))
    if pngs:
        target = Path(__file__).resolve().parent.parent / "test-output" / "contact_sheet.png"
        print(f"\ncontact sheet of {len(pngs)} pictures: {contact_sheet(pngs, target)}")
