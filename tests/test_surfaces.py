"""Real surfaces (SPEC §15): spheres, cylinders and height fields, with Coulomb friction.

Each check is against a closed form or an independent run: the regularised Coulomb law at
every sample, a linear height field against the tilted ``ar.Wall``, a huge sphere against
the plane, a height field sampled from a sphere converging to the sphere, the steady force
on a sphere under computed torque with contact compensation, and sweeps over the new
fields that are the same bits on any thread count and resumed.
"""

import math
from pathlib import Path

import admit_rs as ar
import numpy as np
import pytest

BASE = ar.paper.scenario("fig14").replace(duration=3.0)
DATA = Path(__file__).resolve().parent.parent / "examples" / "data"


def _sliding(wall, **changes):
    return ar.simulate(BASE.replace(wall=wall, **changes))


def test_friction_on_a_plane_is_regularised_coulomb_at_every_sample():
    mu, vs = 0.3, 1e-3
    r = _sliding(ar.Wall(friction=mu, stiction_velocity=vs))
    tr = r.trace
    f, ft, v = (tr[c].to_numpy() for c in ("f", "f_t", "slip_speed"))
    expected = mu * f * v / np.sqrt(v**2 + vs**2)
    touching = f > 0
    assert touching.sum() > 2000
    np.testing.assert_allclose(ft[touching], expected[touching], rtol=1e-9, atol=0)
    # No friction force while f = 0.
    assert np.all(ft[~touching] == 0.0)
    # Sliding fast (|v_t| ≫ v_s) it is μ f.
    fast = touching & (v > 30 * vs)
    assert fast.sum() > 1000
    np.testing.assert_allclose(ft[fast] / f[fast], mu, rtol=1e-3)
    # The force on the surface: f along n (e_x), the drag along the slip (+v_t on the wall).
    np.testing.assert_allclose(tr["fx"].to_numpy(), f, rtol=0, atol=1e-12)
    zdot = np.gradient(tr["z"].to_numpy(), tr["t"].to_numpy())
    moving = fast & (np.abs(zdot) > 0.01)
    assert np.all(np.sign(tr["fz"].to_numpy()[moving]) == np.sign(zdot[moving]))
    # The metric is the mean of f_t over the last 2 s.
    t = tr["t"].to_numpy()
    window = t >= t[-1] - 2.0 - 1e-12
    assert r.metrics["tangential_force_mean"] == pytest.approx(ft[window].mean(), rel=1e-12)
    # Friction is felt by the arm: the run differs from the frictionless one.
    free = _sliding(ar.Wall())
    assert np.all(free.trace["f_t"].to_numpy() == 0.0)
    assert free.metrics["tangential_force_mean"] == 0.0
    assert np.max(np.abs(free.trace["z"].to_numpy() - tr["z"].to_numpy())) > 1e-5


def test_a_linear_height_field_is_the_tilted_wall():
    # h = a u + b v over (u, v) along (t̂, b̂) = (e_z, −e_y) for n = e_x: the plane with
    # normal n − a t̂ − b b̂ = (1, b, −a).
    a, b = 0.2, -0.1
    u = (np.arange(11) - 5) * 0.02
    v = (np.arange(7) - 3) * 0.03
    heights = a * u[:, None] + b * v[None, :] + 0.01
    field = ar.HeightField(heights=heights, spacing=(0.02, 0.03), friction=0.2)
    wall = ar.Wall(normal=(1.0, b, -a), friction=0.2)
    hf, plane = _sliding(field).trace, _sliding(wall).trace
    for column in ("f", "f_t", "x", "y", "z", "tau1", "tau2", "tau3"):
        np.testing.assert_allclose(hf[column].to_numpy(), plane[column].to_numpy(),
                                   rtol=0, atol=1e-9, err_msg=column)  # fmt: skip


def test_a_huge_sphere_is_the_plane():
    sphere = _sliding(ar.Sphere(radius=1e6)).trace["f"].to_numpy()
    plane = _sliding(ar.Wall()).trace["f"].to_numpy()
    assert np.max(np.abs(sphere - plane)) < 1e-6


def _cap(radius, spacing, half_width=0.08):
    """Heights of a ball of radius R seen along n from its point nearest the tool: the
    surface recedes from the tool away from that point, h = R − √(R² − u² − v²) ≥ 0."""
    u = np.arange(-half_width, half_width + 1e-12, spacing)
    r2 = u[:, None] ** 2 + u[None, :] ** 2
    return radius - np.sqrt(radius**2 - r2)


def test_a_height_field_sampled_from_a_sphere_converges_to_the_sphere():
    """The force trace on a height field sampled from a ball (R = 0.3 m) approaches the
    ball's as the grid is refined: 1.7e-3, 8.9e-4, 2.9e-4, 1.7e-4 N at 16, 8, 4, 2 mm. The
    last halvings gain less: the height field's δ is SPEC §15's first-order distance, whose
    error κ δ² tan²θ / 2 (≈ 5e-9 m here, 1.5e-4 N at k_e = 3e4 N/m) is a floor no grid removes
    (docs/surfaces.md)."""
    radius = 0.3
    ref = _sliding(ar.Sphere(radius=radius)).trace["f"].to_numpy()
    errors = []
    for spacing in (0.016, 0.008, 0.004, 0.002):
        field = ar.HeightField(heights=_cap(radius, spacing), spacing=(spacing, spacing))
        f = _sliding(field).trace["f"].to_numpy()
        errors.append(float(np.max(np.abs(f - ref))))
    assert all(a > b for a, b in zip(errors, errors[1:], strict=False)), errors
    assert errors[0] / errors[-1] > 8.0, errors
    assert errors[-1] < 2e-4, errors


@pytest.mark.parametrize("inside", [False, True])
def test_steady_force_on_a_sphere_held_still(inside):
    sc = ar.paper.scenario("fig14").replace(
        controller=ar.ComputedTorque(contact_compensation=True, kp=2500.0, kd=100.0,
                                     command_divisor=1.0),
        wall=ar.Sphere(radius=0.15, inside=inside, normal=(1, 0, 0.3)),
        z_reference=ar.Step(value=0.0),
        duration=4.0,
    )  # fmt: skip
    r = ar.simulate(sc)
    f = r.trace["f"].to_numpy()
    assert abs(f[-1] - 10.0) < 1e-6
    assert abs(r.metrics["force_ss_error"]) < 1e-6


def test_cylinder_axis_motion_feels_no_curvature():
    # Sliding along a cylinder's axis is sliding on a plane.
    shaft = _sliding(ar.Cylinder(radius=0.05, axis=(0, 0, 1))).trace["f"].to_numpy()
    plane = _sliding(ar.Wall()).trace["f"].to_numpy()
    np.testing.assert_allclose(shaft, plane, rtol=0, atol=1e-9)


def test_height_field_from_a_file(tmp_path):
    grid = np.arange(12, dtype=float).reshape(3, 4) * 1e-3
    np.save(tmp_path / "scan.npy", grid)
    np.savetxt(tmp_path / "scan.csv", grid, delimiter=",", header="heights [m]")
    a = ar.HeightField.from_file(tmp_path / "scan.npy", spacing=(0.01, 0.02))
    b = ar.HeightField.from_file(tmp_path / "scan.csv", spacing=(0.01, 0.02))
    assert a == b
    assert np.array_equal(np.asarray(a.heights), grid)
    with pytest.raises(FileNotFoundError, match="no height field file"):
        ar.HeightField.from_file(tmp_path / "missing.csv")


def test_bad_surfaces_name_the_field():
    with pytest.raises(ar.ParameterError, match=r"radius = -1 is invalid"):
        ar.Sphere(radius=-1.0)
    with pytest.raises(ar.ParameterError, match=r"friction = -0.1 is invalid"):
        ar.Wall(friction=-0.1)
    with pytest.raises(ar.ParameterError, match=r"stiction_velocity = 0 is invalid"):
        ar.Sphere(stiction_velocity=0.0)
    with pytest.raises(ar.ParameterError, match=r"axis = .* is invalid"):
        ar.Cylinder(axis=(1, 0, 0))
    with pytest.raises(ar.ParameterError, match=r"heights\[1\]\[0\] = NaN is invalid"):
        ar.HeightField(heights=[[0.0, 0.0], [math.nan, 0.0]])
    with pytest.raises(ar.ParameterError, match=r"heights = a 1×3 grid is invalid"):
        ar.HeightField(heights=[[0.0, 0.0, 0.0]])
    with pytest.raises(ar.ParameterError, match=r"heights = an array of shape \(3,\)"):
        ar.HeightField(heights=[0.0, 0.0, 0.0])
    with pytest.raises(ar.UnknownParameterError, match="did you mean radius"):
        ar.Sphere(radus=0.1)


def test_every_surface_goes_through_toml_and_replace():
    from admit_rs import export

    for wall in (ar.Sphere(radius=0.2, inside=True, friction=0.1),
                 ar.Cylinder(axis=(0, 1, 0), radius=0.3),
                 ar.HeightField(heights=_cap(0.3, 0.02), spacing=(0.02, 0.02))):  # fmt: skip
        sc = BASE.replace(wall=wall, wall_estimate=wall)
        back = ar.Scenario.from_dict(__import__("tomllib").loads(export.toml(sc)))
        assert back == sc
    sc = BASE.replace(wall=ar.Sphere()).replace(**{"wall.radius": 0.5, "wall.friction": 0.2})
    assert (sc.wall.radius, sc.wall.friction) == (0.5, 0.2)


def test_sweeps_over_friction_and_radius_are_the_same_bits_everywhere(tmp_path):
    base = BASE.replace(wall=ar.Sphere(), duration=1.0)
    grid = {"wall.friction": [0.0, 0.1, 0.3, 0.5, 1.0], "wall.radius": [0.05, 0.2, 1.0]}
    one = ar.sweep(base, grid=grid, threads=1, progress=False)
    assert one.equals(ar.sweep(base, grid=grid, threads=2, progress=False))
    assert one.equals(ar.sweep(base, grid=grid, threads=2, chunk_size=4, progress=False))
    ck = tmp_path / "ck"
    first = ar.sweep(base, grid=grid, threads=2, chunk_size=4, checkpoint=ck, progress=False)
    (sorted(ck.glob("*.parquet"))[-1]).unlink()
    resumed = ar.sweep(base, grid=grid, threads=1, chunk_size=4, checkpoint=ck,
                       progress=False)  # fmt: skip
    assert first.equals(resumed) and one.equals(resumed)
    # Each lane run is ar.simulate's within the lanes' tolerance.
    for row in one.iter_rows(named=True):
        alone = ar.simulate(base.replace(**{"wall.friction": row["wall.friction"],
                                            "wall.radius": row["wall.radius"]}))  # fmt: skip
        assert row["force_rms_error"] == pytest.approx(alone.metrics["force_rms_error"],
                                                       rel=1e-9, abs=1e-12)  # fmt: skip
        assert row["tangential_force_mean"] == pytest.approx(
            alone.metrics["tangential_force_mean"], rel=1e-9, abs=1e-12
        )


def test_the_linearised_analysis_at_a_frozen_contact_point():
    """The analysis freezes the motion at s(0): the tool rests on the surface, so regularised
    friction is a viscous damper μ f / v_s along it (3000 N·s/m at μ = 0.3, f = 10 N,
    v_s = 1 mm/s) and the curvature enters through the normal's turn with position."""
    base = ar.paper.scenario("fig14")
    plane = ar.analysis.predict(base)
    # A huge sphere is the plane; a slack regularisation (v_s = 1 km/s) is no friction.
    huge = ar.analysis.predict(base.replace(wall=ar.Sphere(radius=1e6)))
    slack = ar.analysis.predict(base.replace(wall=ar.Wall(friction=0.3, stiction_velocity=1e3)))
    for other in (huge, slack):
        assert other["spectral_radius"] == pytest.approx(plane["spectral_radius"], rel=1e-8)
        assert other["overshoot_pct"] == pytest.approx(plane["overshoot_pct"], rel=1e-5)
    # At rest, stiction damps the tangential motion: the force response changes.
    stuck = ar.analysis.predict(base.replace(wall=ar.Wall(friction=0.3)))
    assert stuck["overshoot_pct"] > plane["overshoot_pct"] + 1.0
    assert abs(stuck["force_ss_error"]) < 1e-9


def test_a_stepped_simulation_on_a_curved_part_resumes_from_its_state():
    """ar.Simulation on a sphere with friction and a curved belief: stepping, saving the
    state, running on and restoring it gives the same samples again (the belief holds no
    state of its own), and the whole stepped run is ar.simulate's."""
    sc = BASE.replace(wall=ar.Sphere(radius=0.2, friction=0.3), duration=1.0)
    sim = ar.Simulation(sc)
    sim.step(400)
    saved = sim.state_vector()
    sim.step(300)
    later = sim.trace["f"].to_numpy()[400:700]
    sim.set_state(saved)
    sim.step(300)
    assert np.array_equal(sim.trace["f"].to_numpy()[400:700], later)
    sim.step(10_000)
    whole = ar.simulate(sc).trace
    assert sim.trace["f"].equals(whole["f"]) and sim.trace["f_t"].equals(whole["f_t"])


# -- UrdfArm(orientation="surface"): the tool kept normal to the estimated surface ----------

PANDA_Q0 = (0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785)


def _misalignment(result, arm, centre):
    """Largest angle [rad] between the tool axis that was along n̂ at the start, R R0ᵀ n̂0,
    and n̂ at the tip now (a ball's inward normal: towards its centre), every 20 samples."""
    cols = [f"q{i + 1}" for i in range(arm.dof)]
    qs = result.trace.select(cols).to_numpy()[::20]
    tips = result.trace.select("x", "y", "z").to_numpy()[::20]
    r0 = arm.dynamics(arm.initial_position)["rotation"]
    n0 = (centre - tips[0]) / np.linalg.norm(centre - tips[0])
    axis0 = r0.T @ n0  # n̂0 in the tool's frame
    worst = 0.0
    for q, tip in zip(qs, tips, strict=True):
        n = (centre - tip) / np.linalg.norm(centre - tip)
        tool = arm.dynamics(q)["rotation"] @ axis0
        worst = max(worst, float(np.arccos(np.clip(tool @ n, -1.0, 1.0))))
    return worst


def test_a_pose_task_can_keep_the_tool_normal_to_a_curved_part():
    """The Panda slides 5 cm each way over a ball of R = 0.3 m: the normal under the tool
    turns by up to 0.05/0.3 = 0.17 rad. Holding R0 leaves the tool that far off the
    normal (0.165 rad measured); orientation="surface" turns it with the normal, within the
    orientation PD's lag (no ω_d feed-forward): 0.0142 rad measured."""
    ball = ar.Sphere(radius=0.3)
    runs = {}
    for mode in ("hold", "surface"):
        arm = ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp", q0=PANDA_Q0, orientation=mode)
        sc = ar.paper.scenario("fig14").replace(
            robot=arm, controller=ar.TimeDelayControl.for_arm(arm), wall=ball, duration=4.0)
        r = ar.simulate(sc)
        assert not r.diverged
        start = r.trace.select("x", "y", "z").row(0)
        centre = np.array(start) + 0.3 * np.array([1.0, 0.0, 0.0])
        runs[mode] = (_misalignment(r, arm, centre), r)
    held, followed = runs["hold"][0], runs["surface"][0]
    assert held == pytest.approx(0.165, abs=0.005), held
    assert followed < 0.02 and followed < held / 10, (followed, held)
    # The force task is unchanged in kind: both press about f_d on the ball.
    for _, r in runs.values():
        assert abs(r.trace["f"].tail(500).mean() - 10.0) < 1.0


def test_orientation_surface_needs_a_pose_task():
    with pytest.raises(ar.ParameterError, match="needs task='pose'") as info:
        ar.UrdfArm(DATA / "three_link.urdf", "tip", orientation="surface")
    assert info.value.field == "orientation"
    with pytest.raises(ar.ParameterError, match="orientation"):
        ar.UrdfArm(DATA / "panda.urdf", "panda_hand_tcp", orientation="normal")  # type: ignore[arg-type]


def test_the_true_surfaces_position_error_beside_an_estimate_is_refused():
    """Issue #53, item 6: with wall_estimate set the controller never reads
    wall.position_error, so a sweep over it returned equal rows without a word."""
    sc = ar.paper.scenario("fig14").replace(duration=0.1, wall_estimate=ar.Wall())
    with pytest.raises(ar.ParameterError) as info:
        sc.replace(**{"wall.position_error": 0.01})
    assert info.value.field == "wall.position_error"
    assert "wall_estimate.position_error" in info.value.allowed
    for kw in ({"vary": {"wall.position_error": ar.Uniform(0.0, 0.01)}, "samples": 2},
               {"grid": {"wall.position_error": [0.0, 0.01]}}):
        with pytest.raises(ar.ParameterError, match="wall_estimate is set"):
            ar.sweep(sc, progress=False, **kw)
    # The estimate's own error is read: moving it moves the force.
    moved = sc.replace(**{"wall_estimate.position_error": 0.005})
    assert ar.simulate(moved).metrics["force_rms_error"] != ar.simulate(sc).metrics[
        "force_rms_error"]


def test_height_field_files_excel_csv_latin1_and_complex(tmp_path):
    """Issue #53, item 17: Excel's "CSV UTF-8" (a byte-order mark) was refused, latin-1
    gave a bare UnicodeDecodeError and a complex .npy lost its imaginary part silently."""
    import numpy as np

    bom = tmp_path / "excel.csv"
    bom.write_bytes("\ufeff0,0.001\n0,0\n".encode())
    assert ar.HeightField.from_file(bom).heights == ((0.0, 0.001), (0.0, 0.0))
    latin = tmp_path / "latin1.csv"
    latin.write_bytes("# scan µm\n0,0.001\n0,0\n".encode("latin-1"))
    with pytest.raises(ar.ParameterError, match="UTF-8") as info:
        ar.HeightField.from_file(latin)
    assert info.value.field == "heights"
    np.save(tmp_path / "complex.npy", np.zeros((2, 2), complex))
    with pytest.raises(ar.ParameterError, match="real heights"):
        ar.HeightField.from_file(tmp_path / "complex.npy")


def test_a_sweep_over_a_height_field_holds_one_copy_of_it():
    """Issue #53, item 16: every run of a sweep decoded and interpolated its own copy of
    the part (a 300 × 300 grid: 720 KB of heights, 2.9 MB of interpolation nodes per run;
    256 runs with ``twin=True`` grew the peak resident set by 276 MB here). Now the runs
    share one table and one interpolation (+33 MB): `benches/height_field_memory.py`."""
    import subprocess
    import sys

    bench = Path(__file__).resolve().parents[1] / "benches" / "height_field_memory.py"
    out = subprocess.run([sys.executable, str(bench), "--twin"], capture_output=True,
                         text=True, timeout=600, check=True).stdout  # fmt: skip
    growth = float(out.rsplit("(+", 1)[1].split(" MB")[0])
    # +33 MB measured (the batch's configs, traces dropped, one grid); +276 MB before.
    assert out.startswith("256 runs") and growth < 100.0, out
