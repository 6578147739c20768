"""Configuration: frozen dataclasses, dotted replace, and every error path (part 11)."""

from __future__ import annotations

import dataclasses
import math

import admit_rs as ar
import pytest
from admit_rs import config


def test_defaults_are_the_paper_preset():
    sc = ar.Scenario()
    assert isinstance(sc.controller, ar.TimeDelayControl)
    ctl = sc.controller
    assert ctl.command_divisor == 5.0 and ctl.kd == 20.0 and ctl.kp == 100.0
    assert sc.controller.inertia == 0.1 and sc.controller.torque_constant == 200.0
    assert sc.admittance == ar.AdmittanceFilter(m=1.0, b=800.0, k=0.0, ka=1.0)
    assert sc.wall == ar.Wall(stiffness=30_000.0, position=None, position_error=0.0)
    assert sc.period == 1e-3 and sc.substeps == 10 and sc.duration == 10.0
    assert sc.samples == 10_001
    assert ar.ComputedTorque().command_divisor == 0.1
    assert sc.robot.q0 == (0.0, math.pi / 4, -math.pi / 4)


def test_blocks_are_frozen_and_keyword_only():
    with pytest.raises(dataclasses.FrozenInstanceError):
        ar.Wall().stiffness = 1.0  # type: ignore[misc]
    with pytest.raises(TypeError):
        ar.Wall(1e4)  # type: ignore[misc]


@pytest.mark.parametrize(
    "cls",
    [
        ar.Robot,
        ar.Wall,
        ar.ModelError,
        ar.ComputedTorque,
        ar.ModelFree,
        ar.TimeDelayControl,
        ar.AdmittanceFilter,
        ar.ImpedanceReference,
        ar.Step,
        ar.Sine,
        ar.Sampled,
        ar.Scenario,
    ],
)
def test_unknown_keyword_is_a_type_error(cls):
    with pytest.raises(TypeError, match="stifness"):
        cls(stifness=1.0)


def test_replace_with_dotted_paths():
    sc = ar.paper.scenario("fig14")
    sc2 = sc.replace(
        **{
            "wall.stiffness": 5e4,
            "wall.position_error": 0.01,
            "controller.model.mass_scale": 1.2,
            "admittance.b": 400.0,
        },
        duration=2.0,
    )
    assert sc2.wall.stiffness == 5e4 and sc2.wall.position_error == 0.01
    assert sc2.controller.model.mass_scale == 1.2
    assert sc2.admittance.b == 400.0 and sc2.duration == 2.0
    assert sc.wall.stiffness == 30_000.0  # the original is untouched
    assert sc2.replace(controller=ar.ModelFree()).controller == ar.ModelFree()


def test_replace_unknown_path_suggests_close_ones():
    with pytest.raises(TypeError, match=r"wall\.stifness.*did you mean wall\.stiffness"):
        ar.Scenario().replace(**{"wall.stifness": 1.0})
    with pytest.raises(TypeError, match="no such parameter"):
        ar.Scenario().replace(**{"nonsense": 1.0})
    with pytest.raises(TypeError, match="wall is NoneType"):
        ar.paper.scenario("fig5").replace(**{"wall.stiffness": 1.0})


def test_replace_validates():
    with pytest.raises(ar.ParameterError, match=r"stiffness = -5"):
        ar.Scenario().replace(**{"wall.stiffness": -5.0})


def test_parameter_paths_cover_nested_fields():
    paths = ar.parameter_paths(ar.Scenario())
    for p in [
        "wall.stiffness",
        "wall.position_error",
        "controller.model.mass_scale",
        "admittance.b",
        "admittance.ka",
        "robot.masses",
        "duration",
    ]:
        assert p in paths


def test_dict_round_trip():
    for sc in ar.paper.scenarios("fig20") + ar.paper.scenarios("fig5"):
        assert ar.Scenario.from_dict(sc.to_dict()) == sc


# --- every invalid parameter: a ValueError subclass naming field, value and range ---------

BAD_BLOCKS = [
    (lambda: ar.Robot(masses=(30.0, 0.0, 4.8)), "masses[1]", "> 0"),
    (lambda: ar.Robot(lengths=(0.66, -0.43, 0.43)), "lengths[1]", "> 0"),
    (lambda: ar.Robot(mass_model="blob"), "mass_model", "'rod', 'point'"),
    (lambda: ar.Robot(gravity=math.nan), "gravity", "finite"),
    (lambda: ar.Robot(q0=(0.0, math.inf, 0.0)), "q0[1]", "finite"),
    (lambda: ar.Robot(viscous_friction=(-1.0, 3.0, 3.0)), "viscous_friction[0]", ">= 0"),
    (lambda: ar.Robot(q0=(0.0, 0.5, 0.0)), "q0", "regular Jacobian"),
    (lambda: ar.Robot(q0=(0.0, math.pi / 2, 0.3)), None, None),  # regular: no error
    (lambda: ar.Wall(stiffness=-1.0), "stiffness", ">= 0"),
    (lambda: ar.Wall(position_error=math.nan), "position_error", "finite"),
    (lambda: ar.ComputedTorque(command_divisor=0.0), "command_divisor", "> 0"),
    (lambda: ar.ModelFree(kd=-1.0), "kd", ">= 0"),
    (lambda: ar.ModelFree(inertia=0.0), "inertia", "> 0"),
    (lambda: ar.TimeDelayControl(torque_constant=math.inf), "torque_constant", "> 0"),
    (lambda: ar.TimeDelayControl(law="eq99"), "law", "'jacobian_transpose'"),
    (lambda: ar.ModelError(mass_scale=0.0), "mass_scale", "> 0"),
    (lambda: ar.AdmittanceFilter(m=0.0), "m", "> 0"),
    (lambda: ar.AdmittanceFilter(b=-1.0), "b", ">= 0"),
    (lambda: ar.AdmittanceFilter(k=-400.0), "k", ">= 0"),
    (lambda: ar.AdmittanceFilter(ka=math.nan), "ka", ">= 0"),
    (lambda: ar.ImpedanceReference(assumed_stiffness=0.0), "assumed_stiffness", "> 0"),
    (lambda: ar.Step(value=math.nan), "value", "finite"),
    (lambda: ar.Sine(omega=math.inf), "omega", "finite"),
    (lambda: ar.Sampled(times=(0.0, 1.0, 1.0), values=(0, 1, 2)), "times[2]", "increasing"),
    (lambda: ar.Sampled(times=(0.0, 1.0), values=(0.0,)), "values", "one value per time"),
    (lambda: ar.Scenario(period=0.0), "period", "> 0"),
    (lambda: ar.Scenario(period=-1e-3), "period", "> 0"),
    (lambda: ar.Scenario(duration=0.0), "duration", "> 0"),
    (lambda: ar.Scenario(duration=0.0105), "duration", "multiple of period"),
    (lambda: ar.Scenario(substeps=0), "substeps", "from 1"),
    (lambda: ar.Scenario(substeps=2.5), "substeps", "integer from 1"),  # type: ignore[arg-type]
    (lambda: ar.Scenario(duration=1e6), "duration", "at most"),
    (lambda: ar.Scenario(velocity_limit=math.nan), "velocity_limit", "> 0"),
]


@pytest.mark.parametrize(("make", "field", "allowed"), BAD_BLOCKS)
def test_invalid_parameters_raise_parameter_error(make, field, allowed):
    if field is None:
        make()
        return
    with pytest.raises(ar.ParameterError) as info:
        make()
    err = info.value
    assert isinstance(err, ValueError)
    assert err.field == field
    assert allowed in err.allowed
    assert str(err).startswith(f"{field} = ")


def test_scenario_level_errors_name_the_dotted_path():
    with pytest.raises(ar.ParameterError) as info:
        ar.Scenario().replace(**{"controller.model.friction_scale": -1.0})
    assert info.value.field == "controller.model.friction_scale"
    assert str(info.value).startswith("controller.model.friction_scale = -1 is invalid")
    # The full scenario check reports the path inside the scenario.
    sc = ar.Scenario()
    bad = sc.to_dict()
    bad["wall"]["stiffness"] = -3.0
    with pytest.raises(ar.ParameterError) as info:
        ar.Scenario.from_dict(bad)
    assert info.value.field == "stiffness"
    from admit_rs import _core

    core = sc._to_core()  # the dict the core decodes by its serde declaration
    core["wall"]["stiffness"] = -3.0
    with pytest.raises(ar.ParameterError) as info:
        _core.validate(core)
    assert info.value.field == "wall.stiffness"
    assert info.value.value == "-3"


def test_wrong_types_are_type_errors():
    with pytest.raises(TypeError, match="controller must be"):
        ar.Scenario(controller="tdc")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="admittance must be"):
        ar.Scenario(admittance=ar.Wall())  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="must be a number"):
        ar.Wall(stiffness="stiff")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="3 elements"):
        ar.Robot(masses=(1.0, 2.0))  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="simulate"):
        ar.simulate({"robot": {}})  # type: ignore[arg-type]


def test_signals_evaluate_in_python_like_in_rust():
    sine = ar.Sine(offset=10.0, amplitude=5.0, omega=1.0)
    assert sine(math.pi / 2) == pytest.approx(15.0)
    assert float(ar.Step(value=10.0, time=1.0)(0.5)) == 0.0
    samp = ar.Sampled(times=[0.0, 2.0], values=[0.0, 4.0])
    assert float(samp(1.0)) == 2.0


# --- help(ar.Wall) and friends: fields with meaning, unit, default ---------------------

BLOCKS = list(config._BLOCKS)  # every public block (tests/test_errors.py checks the list)


def test_every_block_is_documented_force_sensor_and_actuator_included():
    assert {ar.ForceSensor, ar.Actuator, ar.UrdfArm, ar.Scenario} <= set(BLOCKS)


@pytest.mark.parametrize("cls", BLOCKS, ids=lambda c: c.__name__)
def test_block_docstring_lists_every_field_with_its_meaning(cls):
    doc = cls.__doc__
    assert "Fields (keyword-only; units in brackets):" in doc
    for f in dataclasses.fields(cls):
        line = f"\n    {f.name} ({f.type}, default "
        assert line in doc, f.name
        # Every field has a meaning line under it (from its attribute docstring).
        after = doc.split(line, 1)[1].split("\n", 2)
        assert after[1].startswith("        ") and len(after[1].strip()) > 5, f.name


def test_block_docstrings_give_units_and_defaults():
    assert (
        "    stiffness (float, default 30000.0)\n"
        "        Environment stiffness k_e [N/m] (Hunt–Crossley: [N/m^p]); unknown to the "
        "controller." in ar.Wall.__doc__
    )
    assert "    b (float, default 800.0)\n        Damping [N·s/m]." in ar.AdmittanceFilter.__doc__
    assert "    omega (float, default 1.0)\n        Angular frequency [rad/s], >= 0" in (
        ar.Sine.__doc__
    )
    # Inherited fields take their base class's text.
    assert (
        "    inertia (float | tuple[float, ...] | tuple[tuple[float, ...], ...], default 0.1)\n"
        "        Constant inertia D̄ [kg·m²]: one number (D̄ = α I, the paper's)"
    ) in ar.ModelFree.__doc__
    assert "command_divisor (float, default 0.1)\n        K_A of eq. (39)" in (
        ar.ComputedTorque.__doc__
    )
    assert "    ka: deprecated name of command_divisor; warns." in ar.TimeDelayControl.__doc__
    assert "    period (float, default 0.001)\n        Controller period T [s]." in (
        ar.Scenario.__doc__
    )
    assert (
        "    noise_std (float, default 0.0)\n"
        "        Standard deviation of white Gaussian noise [N], on each axis."
    ) in ar.ForceSensor.__doc__
    assert (
        "    torque_limit (float | tuple[float, ...] | None, default None)\n"
        "        |τ_j| limit [N·m]: one number for every joint or one per joint"
    ) in ar.Actuator.__doc__


def test_replace_drops_a_label_it_would_make_false():
    # Issue 21 item 9: a label describes the scenario it was written for.
    from pathlib import Path

    urdf = Path(__file__).parent.parent / "examples" / "data" / "panda.urdf"
    panda = ar.UrdfArm(urdf, "panda_hand_tcp", q0=(0, -0.785, 0, -2.356, 0, 1.571, 0.785))
    sc = ar.paper.scenario("fig14")
    assert sc.label == "TDC, Scheme 2, k_a=1"
    moved = sc.replace(robot=panda, controller=ar.ComputedTorque())
    assert moved.label == ""
    assert ar.describe(moved) == (
        "panda arm (panda_hand_tcp), CT, Scheme 2 (b=800, k_a=1), k_e=30 000, f_d step 10 N"
    )
    assert sc.replace(**{"admittance.ka": 2.0}).label == ""
    assert sc.replace(duration=10.0).label == sc.label  # nothing changed
    assert sc.replace(duration=2.0, label="short").label == "short"
    assert sc.replace(label="mine").replace(label="mine", duration=2.0).label == "mine"


def test_describe_and_wall_directions():
    n, t = ar.Wall(normal=(0, 0, 2)).directions()
    assert n.tolist() == [0.0, 0.0, 1.0] and t.tolist() == [1.0, 0.0, 0.0]  # n ∥ e_z: t = e_x
    assert not ar.Wall().tilted and ar.Wall(normal=(1, 0, -1)).tilted
    assert ar.describe(ar.paper.scenario("fig20")) == (
        "three-link arm, TDC, Scheme 2 (b=800, k_a=1), k_e=10 000, wall error 0.01 m,"
        " f_d 10 + 5 sin(1 t) N"
    )
    with pytest.raises(TypeError, match="describe\\(\\) takes an admit_rs.Scenario"):
        ar.describe(ar.Wall())
