"""Shared fixtures; tests marked ``ngspice`` need the ngspice library and executable."""

import ctypes.util
import os
import shutil
import tempfile

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
