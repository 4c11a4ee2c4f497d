"""kins: round trips, closed forms, rod-length invariants, Jacobian vs finite differences, errors."""
import math
from pathlib import Path

import numpy as np
import pytest

from kins import MachineFileError, WorkspaceError, available_machines, load_machine

MACHINES = ["keops", "kossel", "linuxcnc_delta", "pn101"]


def workspace_grid(m, n=9):
    """A grid over the machine's box, restricted to points whose joints are within stroke."""
    axes = [np.linspace(lo, hi, n) for lo, hi in zip(m.workspace_min, m.workspace_max)]
    P = np.stack([g.ravel() for g in np.meshgrid(*axes, indexing="ij")], axis=1)
    Q, reach = m._ik(P)
    ok = (reach >= 0).all(axis=1) & (Q >= m.q_min).all(axis=1) & (Q <= m.q_max).all(axis=1)
    return P[ok]


def test_all_machines_listed():
    assert available_machines() == sorted(MACHINES)


@pytest.mark.parametrize("name", MACHINES)
def test_fk_inverts_ik_on_workspace_grid(name):
    m = load_machine(name)
    P = workspace_grid(m)
    assert len(P) > 300          # the grid really covers the box
    err = np.abs(m.fk(m.ik(P)) - P).max()
    assert err < 1e-9


@pytest.mark.parametrize("name", MACHINES)
def test_rod_lengths_constant(name):
    m = load_machine(name)
    P = workspace_grid(m)
    carriage, effector = m.joint_points(P)
    if m.family == "pn101":
        # leg 3 is planar in x-z (eq 7); lengths c1, c2, c3
        lengths = np.array([m.params["c1"], m.params["c2"], m.params["c3"]])
    else:
        lengths = np.full(3, m.params["L"])
    rod = np.linalg.norm(carriage - effector, axis=2)
    assert np.abs(rod - lengths[None]).max() < 1e-9


@pytest.mark.parametrize("name", MACHINES)
def test_jacobian_matches_central_differences(name):
    m = load_machine(name)
    P = workspace_grid(m, 5)
    J = m.jacobian(P)
    h = 1e-4
    Jfd = np.empty_like(J)
    for k in range(3):
        e = np.zeros(3)
        e[k] = h
        Jfd[:, :, k] = (m.ik(P + e) - m.ik(P - e)) / (2 * h)
    scale = np.abs(J).max(axis=(1, 2), keepdims=True)
    assert (np.abs(J - Jfd) / scale).max() < 1e-6


@pytest.mark.parametrize("name,L,R", [("kossel", 183.0, 100.0), ("linuxcnc_delta", 269.0, 130.25)])
def test_linear_delta_on_axis_closed_form(name, L, R):
    m = load_machine(name)
    for z in (m.home[2] - 20, m.home[2], m.home[2] + 20):
        q = m.ik([0.0, 0.0, z])
        np.testing.assert_allclose(q, z + math.sqrt(L * L - R * R), rtol=0, atol=1e-12)


def test_keops_centre_value():
    q = load_machine("keops").ik([0.0, 0.0, -400.0])
    # DESIGN.md: q ≈ 245 mm at the workspace centre; by hand: E − √(E² − F) with
    # w = (−440, 0, −400), a = (−cos45, 0, −sin45): E = 840/√2, F = 440² + 400² − 350².
    E = 840 / math.sqrt(2)
    F = 440.0**2 + 400.0**2 - 350.0**2
    np.testing.assert_allclose(q, E - math.sqrt(E * E - F), atol=1e-12)
    assert abs(q[0] - 245.1) < 0.05


def test_pn101_fk_matches_paper_equations():
    """Eqs (9)–(11) of Dimić et al. evaluated literally agree with kins' FK."""
    m = load_machine("pn101")
    g = m.params
    P = workspace_grid(m, 4)
    p1, p2, p3 = m.ik(P).T
    xT = g["x_TP"] + (p2**2 + g["c1"] ** 2 - g["c2"] ** 2 - (p1 - g["c4"]) ** 2) / (2 * (p2 - p1 + g["c4"]))
    zT = g["z_TP"] + g["z_o3"] - g["z_p3"] - np.sqrt(g["c3"] ** 2 - (p3 - (xT - g["x_TP"] + g["x_p3"])) ** 2)
    yT = g["y_TP"] - g["d"] - np.sqrt(g["c2"] ** 2 - (p2 - xT + g["x_TP"]) ** 2 - (zT - g["z_TP"] + g["z_p2"]) ** 2)
    np.testing.assert_allclose(np.stack([xT, yT, zT], 1), P, atol=1e-9)


@pytest.mark.parametrize("name", MACHINES)
def test_scalar_and_vector_calls_agree(name):
    m = load_machine(name)
    P = workspace_grid(m, 3)[:7]
    Q = m.ik(P)
    for i in range(len(P)):
        assert np.array_equal(m.ik(P[i]), Q[i])
        assert np.array_equal(m.fk(Q[i]), m.fk(Q)[i])
        assert np.array_equal(m.jacobian(P[i]), m.jacobian(P)[i])
    assert m.ik(P[0]).shape == (3,) and m.jacobian(P[0]).shape == (3, 3)


def test_ik_unreachable_point_names_index_joint_and_excess():
    m = load_machine("keops")
    P = np.array([[0.0, 0.0, -400.0], [0.0, 0.0, -400.0], [0.0, 0.0, -1000.0]])
    with pytest.raises(WorkspaceError) as e:
        m.ik(P)
    assert e.value.index == 2 and e.value.joint == 1
    assert "point #2" in str(e.value) and "rod 1" in str(e.value)


def test_ik_stroke_exceeded_names_joint_and_amount():
    m = load_machine("kossel")
    # at (0, 0, z) every joint is z + 153.26…; z = -120 puts them 8.26 mm above q_max = 25
    with pytest.raises(WorkspaceError) as e:
        m.ik([[0.0, 0.0, -200.0], [0.0, 0.0, -120.0]])
    excess = -120.0 + math.sqrt(183.0**2 - 100.0**2) - 25.0
    assert e.value.index == 1 and e.value.joint == 1
    assert e.value.excess_mm == pytest.approx(excess, abs=1e-9)
    assert "stroke limit 25" in str(e.value)


def test_check_reports_every_problem_without_raising():
    m = load_machine("kossel")
    P = np.array([[0.0, 0.0, -200.0],      # fine
                  [0.0, 0.0, -120.0],      # stroke on all three joints, outside box
                  [300.0, 0.0, -200.0]])   # unreachable by rods 1? at least one
    f = m.check(P)
    assert not [x for x in f if x.index == 0]
    stroke = [x for x in f if x.index == 1 and x.kind == "stroke"]
    assert sorted(x.joint for x in stroke) == [1, 2, 3]
    assert any(x.kind == "box" for x in f if x.index == 1)
    unreach = [x for x in f if x.index == 2 and x.kind == "unreachable"]
    assert unreach and all(x.value > 0 for x in unreach)


def test_singularity_flagged_by_condition_number():
    m = load_machine("pn101")
    # Y + d → 0 makes legs 1, 2 insensitive to y: cond(J) → ∞ (pn101.py docstring)
    c = m.condition_number([[0.0, -m.params["d"] - 1e-3, 0.0]])
    assert c > 1e4
    f = m.check([[0.0, -m.params["d"] - 1e-3, 0.0]])
    assert any(x.kind == "singularity" and x.value > m.cond_max for x in f)


@pytest.mark.parametrize("name", MACHINES)
def test_check_flags_exactly_where_the_condition_number_exceeds_cond_max(name):
    # check() runs the SVD only where ‖J‖_F³/|det J| (a bound on σ₁/σ₃) does not clear
    # cond_max: its singularity findings are condition_number's, point for point and value for
    # value, on points in and around the box (near the bound's limit and far from it)
    m = load_machine(name)
    span = m.workspace_max - m.workspace_min
    P = np.random.default_rng(3).uniform(m.workspace_min - 0.3 * span, m.workspace_max + 0.3 * span, (40000, 3))
    cond = m.condition_number(P)
    _, reach = m._ik(P)
    expected = [(int(i), float(cond[i])) for i in np.nonzero((reach >= 0).all(axis=1) & (cond > m.cond_max))[0]]
    found = [(x.index, x.value) for x in m.check(P) if x.kind == "singularity"]
    assert found == expected
    # the bound holds and the SVD is left out almost everywhere in the box
    J = m._jacobian(workspace_grid(m))
    bound = np.sqrt((J * J).sum(axis=(1, 2))) ** 3 / np.abs(np.linalg.det(J))
    assert (bound >= np.linalg.cond(J) * (1 - 1e-12)).all()
    assert (bound <= 0.999 * m.cond_max).mean() > 0.6
    if name != "keops":                 # keops has no singularity around its box
        assert len(expected) > 100


def test_ik_rejects_nan_and_bad_shape():
    m = load_machine("keops")
    with pytest.raises(ValueError, match="not finite"):
        m.ik([[0.0, np.nan, -400.0]])
    with pytest.raises(ValueError, match="shape"):
        m.ik(np.zeros((4, 2)))


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    return p


def _keops_text() -> str:
    return (Path(__file__).parent.parent / "benchmarks/machines/keops.toml").read_text()


def test_machine_file_missing_key(tmp_path):
    p = _write(tmp_path, _keops_text().replace("L = 350.0", ""))
    with pytest.raises(MachineFileError, match=r"bad\.toml: missing key 'L' in \[kinematics\]"):
        load_machine(p)


def test_machine_file_negative_length(tmp_path):
    p = _write(tmp_path, _keops_text().replace("L = 350.0", "L = -350.0"))
    with pytest.raises(MachineFileError, match=r"bad\.toml: \[kinematics\] L = -350.0 must be > 0"):
        load_machine(p)


def test_machine_file_limit_zero(tmp_path):
    p = _write(tmp_path, _keops_text().replace("a = 10000.0", "a = 0.0", 1))
    with pytest.raises(MachineFileError, match=r"\[limits.joint\] a = 0.0 must be > 0"):
        load_machine(p)


def test_machine_file_unknown_kinematics(tmp_path):
    p = _write(tmp_path, _keops_text().replace('type = "keops"', 'type = "hexapod"'))
    with pytest.raises(MachineFileError, match=r"type = 'hexapod' is unknown; valid: keops, lineardelta, pn101"):
        load_machine(p)


def test_unknown_machine_lists_valid():
    with pytest.raises(MachineFileError, match="unknown machine 'delta9'; valid: keops, kossel"):
        load_machine("delta9")


def test_machine_file_bad_toml(tmp_path):
    p = _write(tmp_path, "name = ")
    with pytest.raises(MachineFileError, match="not valid TOML"):
        load_machine(p)
