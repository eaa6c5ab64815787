"""The flexible arm's joint frames and gravity's geometric stiffness, against a finite-element frame of Hermite beams.

The finite-element model (``beam_frame.py``) shares nothing with the assumed modes but
the beam's data: 50 Euler–Bernoulli elements a link, inextensible, consistent mass, the
joints as pins or clamps, gravity's axial force in each element. The assumed modes are
a Ritz approximation of the same energy, so their frequencies lie above the exact ones
and fall towards them as modes are added.
"""

import numpy as np
import pytest

from beam_frame import frame_frequencies
from analogy.model.beams import beam_modes, frequency_roots
from analogy.model.flexible import FLEXIBLE_DEFAULTS as D, FlexibleLink, flexible_arm
from analogy.model.joint import JointSpace
from analogy.model.mechanism import flexible_arm_outline
from analogy.results.modes import natural_modes

LINKS = [FlexibleLink(D["l1"], D["rhoA1"], D["EI1"], hub_inertia=D["Jh1"], tip_mass=D["mh2"], tip_inertia=D["Jh2"]),
         FlexibleLink(D["l2"], D["rhoA2"], D["EI2"], tip_mass=D["mp"], tip_inertia=D["Jp"])]
POSE, HANGING, UPRIGHT = [0.3, 0.5], [-np.pi / 2, 0.0], [np.pi / 2, 0.0]
ELEMENTS = 50
# The assumed modes at 4 a link against the finite elements, on the two lowest elastic
# frequencies: the bound. Measured 4e-5 to 4.1e-4 (tip frame, clamped-mass shapes).
BOUND = 1e-3
# The finite elements' rounding: an entry of K is 12·EI/h³ while the lowest mode's strain
# energy is EI·β⁴/L³, so ε·|K| moves ω² by ε·12·n⁴/β⁴ of itself (β = 1.875, the lowest
# elastic mode's): 1.3e-9 at 50 elements.
FE_FLOOR = 12 * np.finfo(float).eps * ELEMENTS ** 4 / 1.875 ** 4


def am_frequencies(model, pose, locked, gravity=True):
    """Signed frequencies [Hz] of the model at *pose* (elastic coordinates 0), joints *locked* held.

    Without *gravity*: M and the bending stiffness alone (G and its stiffness are linear in g,
    so this is the model at g = 0 without building it again)."""
    js = model.joint_space(list(pose) + [0.0] * (model.dof - 2))
    if not gravity:
        js = JointSpace(js.mass_matrix, js.damping, np.array(model.stiffness, dtype=float))
    m = natural_modes(js, locked)
    return np.sign(m.omega_squared) * m.omega / (2 * np.pi)


@pytest.fixture(scope="module")
def tip4():
    """flex2 at its defaults in the tip frame, 4 modes a link (clamped-mass shapes, geometric stiffness)."""
    return flexible_arm(2, joint_frame="tip", modes1=4, modes2=4)


def elastic(frequencies, locked):
    """The two lowest elastic frequencies: past one rigid-body (or pendulum) mode per free joint."""
    free = 2 - len(locked)
    return frequencies[free:free + 2]


def test_the_finite_elements_give_a_loaded_cantilever_s_frequency_equation():
    """A link clamped at its hub, with flex2's elbow motor at its tip: the exact roots λ_k of
    the tip-loaded frequency equation. Cubic Hermite elements with consistent mass converge
    from above as ω_h²/ω² − 1 ≈ (λh/L)⁴/720, so |ω_h/ω − 1| ≤ (λ/50)⁴/720 is their own bound."""
    link = LINKS[0]
    f = frame_frequencies([link], [0.3], locked=[1], elements=ELEMENTS)[:3]
    lam = frequency_roots(3, link.tip_mass / (link.rho_a * link.length), link.tip_inertia / (link.rho_a * link.length ** 3))
    exact = lam ** 2 * np.sqrt(link.ei / (link.rho_a * link.length ** 4)) / (2 * np.pi)
    rel = f / exact - 1
    assert np.all(rel > -FE_FLOOR)
    assert np.all(rel <= (lam / ELEMENTS) ** 4 / 720), rel


@pytest.mark.deep                   # 14 s with its fixture: in CI's deep pass
def test_a_lock_in_the_tip_frame_is_a_clamp_and_one_in_the_axis_frame_is_not(tip4):
    """Both joints locked at (0.3, 0.5), no gravity: a clamped frame. The tip frame's lowest two
    frequencies come to within 1e-3 of the finite elements' 2.2806 and 10.143 Hz at 4 modes a
    link; the axis frame (the paper's) holds link 2's direction to the hub, not to link 1's
    tip, and its first frequency is 3.41 Hz (3.415 at 2 modes, 3.409 at 4)."""
    fe = frame_frequencies(LINKS, POSE, locked=[1, 2], elements=ELEMENTS)[:2]
    tip = am_frequencies(tip4, POSE, [1, 2], gravity=False)[:2]
    axis = am_frequencies(flexible_arm(2, joint_frame="axis"), POSE, [1, 2], gravity=False)[:2]
    assert fe[0] == pytest.approx(2.2806, abs=1e-4)
    assert np.all(tip >= fe * (1 - FE_FLOOR)) and np.all(tip / fe - 1 < BOUND), tip / fe - 1
    assert axis[0] / fe[0] > 1.4


@pytest.mark.deep
def test_the_tip_frame_s_frequencies_fall_towards_the_finite_elements_as_modes_are_added():
    """Ritz from above: 2, 3 and 4 modes a link, both joints locked and joint 2 alone."""
    fe = {lk: elastic(frame_frequencies(LINKS, POSE, locked=lk, elements=ELEMENTS), lk) for lk in ((1, 2), (2,))}
    seen = {lk: [] for lk in fe}
    for modes in (2, 3, 4):
        model = flexible_arm(2, joint_frame="tip", modes1=modes, modes2=modes)
        for lk in fe:
            seen[lk].append(elastic(am_frequencies(model, POSE, lk, gravity=False), lk))
    for lk, runs in seen.items():
        runs = np.array(runs)
        assert np.all(runs >= fe[lk] * (1 - FE_FLOOR)), (lk, runs - fe[lk])
        assert np.all(np.diff(runs, axis=0) < 0), (lk, runs)


def test_free_joints_have_the_same_frequencies_in_either_frame():
    """The tip frame is a change of coordinates, q = A·q': with no joint held, M, K and ∂G/∂q
    are congruent and the frequencies agree to rounding (the eigenproblem's 1e-12 of ω²,
    about 100·ε·cond(M)). The same mode shapes in both: each frame has its own default."""
    both = [flexible_arm(2, "clamped-free", joint_frame=frame, geometric_stiffness=True) for frame in ("axis", "tip")]
    for pose in (POSE, HANGING):
        a, b = (am_frequencies(m, pose, []) for m in both)
        np.testing.assert_allclose(b ** 2 * np.sign(b), a ** 2 * np.sign(a), rtol=1e-10, atol=1e-10 * np.max(a ** 2))


@pytest.mark.parametrize("pose", [POSE, HANGING, UPRIGHT], ids=["bent", "hanging", "upright"])
@pytest.mark.parametrize("locked", [(1, 2), (2,), ()], ids=["clamped", "elbow-locked", "free"])
def test_gravity_s_geometric_stiffness_brings_the_arm_to_the_finite_elements(tip4, pose, locked):
    """Under gravity (g = 9.81), at three poses and three sets of locks: the lowest two elastic
    frequencies within 1e-3 of the finite elements, from above."""
    fe = elastic(frame_frequencies(LINKS, pose, gravity=D["g"], locked=locked, elements=ELEMENTS), locked)
    am = elastic(am_frequencies(tip4, pose, locked), locked)
    assert np.all(am >= fe * (1 - FE_FLOOR)) and np.all(am / fe - 1 < BOUND), am / fe - 1


@pytest.mark.deep
def test_without_it_a_hanging_arm_is_too_soft_and_an_upright_one_too_stiff():
    """The missing physics has a sign: an axial tension stiffens a hanging link and a
    compression softens an upright one, both joints clamped (FE 2.3185 and 2.1393 Hz)."""
    plain = flexible_arm(2, joint_frame="tip", geometric_stiffness=False, modes1=4, modes2=4)
    for pose, sign in ((HANGING, -1), (UPRIGHT, 1)):
        fe = frame_frequencies(LINKS, pose, gravity=D["g"], locked=[1, 2], elements=ELEMENTS)[0]
        am = am_frequencies(plain, pose, [1, 2])[0]
        assert sign * (am / fe - 1) > 10 * BOUND, (pose, am / fe - 1)


def test_in_the_tip_frame_the_elbow_angle_is_measured_from_link_1_s_deformed_tip():
    """The drawn arm, link 1 bent and link 2 straight: link 2 points along θ1 + ψ'(l1)·δ1 + θ2
    in the tip frame, along θ1 + θ2 in the axis frame (to rounding)."""
    q = np.array([[0.3, 0.5, 0.02, -0.004, 0.0, 0.0]])
    loaded = beam_modes(2, D["l1"], D["rhoA1"], D["EI1"], D["mh2"], D["Jh2"])
    tip_slope = float(loaded.shape([D["l1"]], 1)[0] @ q[0, 2:4])
    for frame, expected in (("tip", 0.3 + tip_slope + 0.5), ("axis", 0.3 + 0.5)):
        link2 = flexible_arm_outline(q, dict(D), joint_frame=frame)[0][1]
        direction = np.arctan2(*(link2[-1] - link2[0])[::-1])
        assert direction == pytest.approx(expected, abs=1e-12)
    assert abs(tip_slope) > 0.01
