"""Shared fixtures; tests marked ``ngspice`` need the ngspice library and executable."""

import atexit
import ctypes.util
import os
import shutil
import tempfile
from pathlib import Path

import pytest

# Compiled models go to a cache of the test run's own, never the user's, removed when the run ends
# (pytest-xdist's workers inherit the controller's, which outlives them).
if "ANALOGY_CACHE_DIR" not in os.environ:
    os.environ["ANALOGY_CACHE_DIR"] = tempfile.mkdtemp(prefix="analogy-test-cache-")
    atexit.register(shutil.rmtree, os.environ["ANALOGY_CACHE_DIR"], ignore_errors=True)

HAVE_LIBRARY = bool(os.environ.get("NGSPICE_LIBRARY_PATH") or ctypes.util.find_library("ngspice"))
HAVE_EXECUTABLE = shutil.which("ngspice") is not None


#: Instances of 3 s and more whose property the default pass checks on a smaller case beside them:
#: in CI's deep pass (pytest -m deep), so that the default pass stays near five minutes.
DEEP_INSTANCES = {
    "test_report.py::test_a_report_flags_the_output_past_its_bound_and_exits_3",        # exit 3: test_cli
    "test_flexible_frames.py::test_gravity_s_geometric_stiffness_brings_the_arm_to_the_finite_elements[clamped-bent]",
    "test_flexible_frames.py::test_free_joints_have_the_same_frequencies_in_either_frame",
    "test_flexible_parallel.py::test_the_assumed_modes_converge_from_above_to_the_finite_element_frame[locked-oblique]",
    "test_flexible_parallel.py::test_gravity_s_geometric_stiffness_needs_the_loop_s_foreshortening",
    "test_flexible_parallel.py::test_modes_from_the_command_line_are_the_model_s",
    "test_flexible_parallel.py::test_gravity_s_stiffness_is_the_derivative_of_its_load_along_the_loop",
    "test_flexible.py::test_the_built_in_arm_is_rebuilt_when_a_parameter_changes",
    "test_nonlinear.py::test_a_swing_that_collapsed_at_stale_pivots_runs_trapezoidal_within_its_bound",
    "test_labs.py::test_lab_runs_as_a_notebook[lab_serial2.py]",                 # the default scene's lab stays
    "test_urdf_nonlinear.py::test_the_same_holds_for_random_trees_and_the_hand_written_bench[1]",
    "test_urdf_nonlinear.py::test_the_same_holds_for_random_trees_and_the_hand_written_bench[2]",
    "test_urdf_nonlinear.py::test_the_circuit_s_capacitances_and_load_are_the_tree_s_mass_matrix_and_lagrange_terms[panda]",
    "test_batch.py::test_throughput_reports_the_ngspice_floor_beside_the_batched_path",
    "test_work.py::test_every_named_robot_runs_nonlinear_inside_the_budget",
    "test_robots.py::test_serial_arms_match_pinocchio[serial6]",
    "test_compiled.py::test_a_flexible_arm_is_compiled_per_parameter_set_and_a_later_process_needs_no_sympy[args0]",
    "test_scenefile.py::test_a_scene_file_chooses_the_flexible_arm_s_joint_frame_and_geometric_stiffness",
    "test_estimate.py::test_check_flags_a_fast_netlist_against_the_accurate_bound",
}


@pytest.hookimpl(tryfirst=True)         # before -m deselects by mark
def pytest_collection_modifyitems(config, items):
    for item in items:
        if item.nodeid.partition("/")[2] in DEEP_INSTANCES:
            item.add_marker(pytest.mark.deep)
    # In CI ngspice is installed by setup.sh, so a missing ngspice there is a failure, not a skip.
    if os.environ.get("CI") or (HAVE_LIBRARY and HAVE_EXECUTABLE):
        return
    skip = pytest.mark.skip(reason="ngspice is not installed (run: bash setup.sh test)")
    for item in items:
        if "ngspice" in item.keywords:
            item.add_marker(skip)


def pytest_sessionfinish(session):
    """After the run: test-output/contact_sheet.png tiles every picture the tests wrote (in the process
    that ran them, or with pytest-xdist in the controller, whose base folder holds each worker's)."""
    if hasattr(session.config, "workerinput"):
        return
    factory = getattr(session.config, "_tmp_path_factory", None)
    if factory is None:
        return
    from contact_sheet import contact_sheet
    pngs = sorted(factory.getbasetemp().rglob("*.png"))
    if pngs:
        target = Path(__file__).resolve().parent.parent / "test-output" / "contact_sheet.png"
        print(f"\ncontact sheet of {len(pngs)} pictures: {contact_sheet(pngs, target)}")
