"""One exception root, unknown names with suggestions, TOML kinds, the renamed K_A."""

from __future__ import annotations

import dataclasses
import difflib
import inspect
import math
import sys
import warnings
from pathlib import Path

import admit_rs as ar
import pytest
import tomllib
from admit_rs import _core, config, errors
from admit_rs._names import check_column

# --- one root ---------------------------------------------------------------------------


def _exported_exceptions():
    found = {}
    for module in (ar, errors, sys.modules["admit_rs.sweep"], sys.modules["admit_rs.config"]):
        for name in dir(module):
            obj = getattr(module, name)
            if (
                inspect.isclass(obj)
                and issubclass(obj, BaseException)
                and obj.__module__.startswith("admit_rs")  # defined here, not imported
            ):
                found[name] = obj
    return found


def test_every_exported_exception_derives_from_admit_error():
    found = _exported_exceptions()
    # The walk must see the classes it is meant to check.
    assert {"AdmitError", "ParameterError", "UnknownParameterError", "DistributionError",
            "CheckpointMismatchError", "SweepInterrupted"} <= set(found)  # fmt: skip
    for name, cls in found.items():
        if issubclass(cls, Warning):  # warned, never raised (CheckpointWarning)
            continue
        if cls is ar.SweepInterrupted:
            # Deliberately a KeyboardInterrupt only: AdmitError is an Exception, and
            # `except Exception` must not swallow a Ctrl-C.
            assert issubclass(cls, KeyboardInterrupt) and not issubclass(cls, Exception)
            continue
        assert issubclass(cls, ar.AdmitError), name
    assert issubclass(ar.ParameterError, ValueError)
    assert issubclass(ar.UnknownParameterError, TypeError)
    assert issubclass(ar.DistributionError, ValueError)
    assert issubclass(ar.CheckpointMismatchError, ValueError)


def test_errors_raised_by_the_rust_core_are_admit_errors():
    with pytest.raises(ar.AdmitError) as info:
        ar.Wall(stiffness=-1.0)
    assert type(info.value) is ar.ParameterError and isinstance(info.value, ValueError)
    assert info.value.field == "stiffness" and info.value.allowed == "finite and >= 0"
    with pytest.raises(ar.AdmitError, match="low = 2.0 > high = 1.0"):
        ar.Uniform(2.0, 1.0)


# --- unknown keywords on every block ----------------------------------------------------

MISSPELLED = [
    (ar.Robot, "mases", "masses"),
    (ar.Wall, "stifness", "stiffness"),
    (ar.ModelError, "mass_scal", "mass_scale"),
    (ar.ComputedTorque, "contact_compensaton", "contact_compensation"),
    (ar.ModelFree, "torque_constnt", "torque_constant"),
    (ar.TimeDelayControl, "laww", "law"),
    (ar.AdmittanceFilter, "bb", "b"),
    (ar.ImpedanceReference, "assumed_stifness", "assumed_stiffness"),
    (ar.Step, "valeu", "value"),
    (ar.Sine, "amplitud", "amplitude"),
    (ar.Sampled, "time", "times"),
    (ar.Scenario, "duraton", "duration"),
    (ar.ForceSensor, "noise_stdd", "noise_std"),
    (ar.Actuator, "torque_limt", "torque_limit"),
    (ar.UrdfArm, "tip_lnk", "tip_link"),
    (ar.Criteria, "force_limt", "force_limit"),
    (ar.GuardedApproach, "threshhold", "threshold"),
    (ar.Sphere, "radus", "radius"),
    (ar.Cylinder, "axiss", "axis"),
    (ar.HeightField, "spacng", "spacing"),
]


@pytest.mark.parametrize(("cls", "typo", "right"), MISSPELLED)
def test_every_block_suggests_the_closest_keyword(cls, typo, right):
    with pytest.raises(ar.UnknownParameterError) as info:
        cls(**{typo: 1.0})
    assert isinstance(info.value, TypeError) and isinstance(info.value, ar.AdmitError)
    assert str(info.value).startswith(f"{cls.__name__}: unknown keyword {typo!r}; did you mean")
    assert info.value.suggestions[0] == right
    assert info.value.name == typo


def _exported_blocks() -> list[type]:
    """Every public block class: the frozen dataclasses of admit_rs.blocks that admit_rs
    exports (found, not listed, so a new block cannot be left out)."""
    found = []
    for name in ar.__all__:
        obj = getattr(ar, name)
        if (
            inspect.isclass(obj)
            and dataclasses.is_dataclass(obj)
            and obj.__module__.startswith("admit_rs.blocks.")
            and obj.__dataclass_params__.frozen
        ):
            found.append(obj)
    return found


EXPORTED_BLOCKS = _exported_blocks()


def test_the_block_walk_sees_every_block():
    names = {cls.__name__ for cls in EXPORTED_BLOCKS}
    assert {"Robot", "UrdfArm", "Wall", "ForceSensor", "Actuator", "ModelError",
            "ComputedTorque", "ModelFree", "TimeDelayControl", "AdmittanceFilter",
            "ImpedanceReference", "Step", "Sine", "Sampled", "Scenario"} <= names  # fmt: skip
    # config guards and documents exactly these.
    assert set(EXPORTED_BLOCKS) == set(config._BLOCKS)
    # The explicit typo table above covers every block too.
    assert {cls for cls, _, _ in MISSPELLED} == set(EXPORTED_BLOCKS)


@pytest.mark.parametrize("cls", EXPORTED_BLOCKS, ids=lambda c: c.__name__)
def test_every_exported_block_rejects_an_unknown_keyword_with_a_suggestion(cls):
    field = max((f.name for f in dataclasses.fields(cls)), key=len)
    typo = field + field[-1]
    with pytest.raises(ar.UnknownParameterError) as info:
        cls(**{typo: 1.0})
    err = info.value
    assert isinstance(err, TypeError) and isinstance(err, ar.AdmitError)
    assert (err.name, err.suggestions[0]) == (typo, field)
    assert str(err).startswith(f"{cls.__name__}: unknown keyword {typo!r}; did you mean {field}")


def test_force_sensor_and_actuator_suggest_like_every_block():
    with pytest.raises(ar.UnknownParameterError) as info:
        ar.ForceSensor(noise_stdd=1)
    assert str(info.value) == "ForceSensor: unknown keyword 'noise_stdd'; did you mean noise_std?"
    assert info.value.suggestions == ["noise_std"]
    with pytest.raises(ar.UnknownParameterError) as info:
        ar.Actuator(torque_limt=10.0)
    assert str(info.value) == (
        "Actuator: unknown keyword 'torque_limt'; did you mean torque_limit, rate_limit?"
    )
    assert info.value.suggestions == ["torque_limit", "rate_limit"]


def test_no_close_match_lists_the_valid_keywords():
    with pytest.raises(ar.UnknownParameterError) as info:
        ar.Wall(zzz=1.0)
    assert str(info.value) == (
        "Wall: unknown keyword 'zzz'; valid: stiffness, damping, model, exponent, friction, "
        "stiction_velocity, position_error, gap, normal, position"
    )
    assert info.value.suggestions == []


def test_replace_unknown_path_is_an_unknown_parameter_error():
    with pytest.raises(ar.UnknownParameterError) as info:
        ar.Scenario().replace(**{"admittance.bb": 1.0})
    assert str(info.value).startswith("admittance.bb: no such parameter in Scenario; did you")
    assert "admittance.b" in info.value.suggestions


# --- one "closest name" helper ---------------------------------------------------------


def test_every_did_you_mean_comes_from_errors_closest():
    # The only difflib call of the package is errors.closest's.
    package = Path(errors.__file__).parent
    users = sorted(p.name for p in package.glob("*.py") if "difflib" in p.read_text("utf-8"))
    assert users == ["errors.py"]
    assert errors.CLOSE_MATCH_CUTOFF == 0.6
    assert errors.closest("stifness", ["stiffness", "damping"]) == ["stiffness"]


# "force_pek" is close to force_peak, "force_qqqqq" (ratio 0.57) only just not:
# the same cutoff on every surface, keywords, metrics, columns, state entries and figures.
@pytest.mark.parametrize("typo", ["force_pek", "force_qqqqq", "zzz"])
def test_every_surface_suggests_the_same_names(typo):
    metrics = ar.simulate(ar.paper.scenario("fig14").replace(duration=0.1)).metrics
    with pytest.raises(ar.UnknownNameError) as info:
        metrics[typo]
    assert info.value.suggestions == errors.closest(typo, sorted(metrics))
    labels = ["plant.q1", "plant.qd1", "force_peak", "force_pk"]
    with pytest.raises(ar.UnknownNameError) as info:
        check_column(labels, typo)
    assert info.value.suggestions == errors.closest(typo, labels)
    fields = [f.name for f in dataclasses.fields(ar.Wall)]
    with pytest.raises(ar.UnknownParameterError) as err:
        ar.Wall(**{typo: 1.0})
    assert err.value.suggestions == errors.closest(typo, fields)
    sim = ar.Simulation(ar.paper.scenario("fig14").replace(duration=0.1))
    with pytest.raises(ar.UnknownNameError) as info:
        sim.set_state({typo: 0.0})
    assert info.value.suggestions == errors.closest(typo, sim.state_labels)
    assert info.value.kind == "state entry"


def test_the_cutoff_is_the_same_for_names_and_keywords():
    # 0.5 <= ratio < 0.6: suggested by no surface (UnknownNameError used 0.5 before).
    ratio = difflib.SequenceMatcher(None, "force_qqqqq", "force_peak").ratio()
    assert 0.5 <= ratio < errors.CLOSE_MATCH_CUTOFF
    with pytest.raises(ar.UnknownNameError) as info:
        check_column(["force_peak"], "force_qqqqq")
    assert info.value.suggestions == []
    assert str(info.value) == "unknown column 'force_qqqqq'; valid: force_peak"


# --- TOML: keys, kinds ------------------------------------------------------------------


def _toml(text: str) -> ar.Scenario:
    return ar.Scenario.from_dict(tomllib.loads(text))


def test_toml_admittance_without_kind_is_the_filter():
    sc = _toml("[admittance]\nb = 200.0\nka = 2.0\n")
    assert sc.admittance == ar.AdmittanceFilter(m=1.0, b=200.0, k=0.0, ka=2.0)


def test_toml_tables_are_read_by_kind():
    sc = _toml('[admittance]\nkind = "impedance"\nassumed_stiffness = 5e4\n')
    assert sc.admittance == ar.ImpedanceReference(k=10_000.0, assumed_stiffness=5e4)
    sc = _toml('[robot]\nkind = "three_link"\ngravity = 9.0\n')
    assert sc.robot == ar.Robot(gravity=9.0)


def test_toml_kind_chosen_by_keys_is_deprecated_but_still_read():
    # A table without kind whose keys fit only another kind: read as that kind, warning.
    with pytest.warns(DeprecationWarning, match="add kind = 'impedance'"):
        sc = _toml("[admittance]\nassumed_stiffness = 5e4\n")
    assert sc.admittance == ar.ImpedanceReference(k=10_000.0, assumed_stiffness=5e4)
    with pytest.warns(DeprecationWarning, match="add kind = 'computed_torque'"):
        sc = _toml("[controller]\ncontact_compensation = true\n")
    assert type(sc.controller) is ar.ComputedTorque and sc.controller.contact_compensation
    with pytest.warns(DeprecationWarning, match="add kind = 'sine'"):
        sc = _toml("[force_reference]\noffset = 10.0\namplitude = 5.0\n")
    assert sc.force_reference == ar.Sine(offset=10.0, amplitude=5.0)
    # Keys the default block has: the default block (TDC, Step), like any omitted field.
    sc = _toml("[controller]\nkd = 30.0\n[force_reference]\nvalue = 4.0\n")
    assert sc.controller == ar.TimeDelayControl(kd=30.0)
    assert sc.force_reference == ar.Step(value=4.0)


def test_toml_unknown_kind_lists_only_the_kinds_valid_there():
    with pytest.raises(ar.UnknownParameterError) as info:
        _toml('[admittance]\nkind = "sine"\n')
    assert str(info.value) == (
        "admittance.kind: unknown kind 'sine' for admittance; one of ['admittance', 'impedance']"
    )
    with pytest.raises(ar.UnknownParameterError) as info:
        _toml('[controller]\nkind = "time_dealy"\n')
    assert "one of ['computed_torque', 'model_free', 'time_delay']" in str(info.value)
    assert info.value.suggestions == ["time_delay"]
    with pytest.raises(ar.UnknownParameterError, match="one of \\['step', 'sine', 'sampled'\\]"):
        _toml('[z_reference]\nkind = "admittance"\n')


def test_toml_keys_that_fit_several_non_default_kinds_need_a_kind():
    # `omega` is a Sine field; `value` a Step field: no single kind has both.
    with pytest.raises(ar.UnknownParameterError) as info:
        _toml("[force_reference]\nomega = 1.0\nvalue = 2.0\n")
    assert "force_reference: unknown key" in str(info.value)
    assert "force_reference kinds: step, sine, sampled" in str(info.value)


def test_toml_key_typos_name_the_path_and_the_closest_key():
    cases = {
        "[wall]\nstifness = 1e4\n": "wall.stifness: unknown key in a Wall table; "
        "did you mean stiffness?",
        "duraton = 2.0\n": "duraton: unknown key in a Scenario table; did you mean duration?",
        '[controller]\nkind = "time_delay"\n[controller.model]\nmass_scle = 1.1\n':
            "controller.model.mass_scle: unknown key in a ModelError table; "
            "did you mean mass_scale?",
        '[admittance]\nkind = "admittance"\nbb = 1.0\n': "admittance.bb: unknown key in an"
        " AdmittanceFilter table; did you mean b?",
    }  # fmt: skip
    for text, message in cases.items():
        with pytest.raises(ar.UnknownParameterError) as info:
            _toml(text)
        assert str(info.value) == message


def test_toml_fixed_table_with_a_kind_is_rejected():
    with pytest.raises(ar.UnknownParameterError, match="a sensor table takes no kind"):
        _toml('[sensor]\nkind = "sensor"\n')
    # A surface table names its kind (SPEC §15); a misspelt one gets the closest.
    with pytest.raises(ar.UnknownParameterError, match=r"unknown kind 'sphre' for wall") as e:
        _toml('[wall]\nkind = "sphre"\n')
    assert e.value.suggestions[0] == "sphere"
    assert isinstance(_toml('[wall]\nkind = "plane"\n').wall, ar.Wall)
    assert isinstance(_toml('[wall]\nkind = "sphere"\nradius = 0.2\n').wall, ar.Sphere)


# --- K_A of eq. 39: controller.command_divisor ------------------------------------------


def test_command_divisor_is_k_a_of_eq_39_and_admittance_ka_is_unchanged():
    sc = ar.paper.scenarios("fig10")[0]  # CT, Scheme 2, b = 800, k_a = 1
    assert sc.controller.command_divisor == 0.1 and sc.admittance.ka == 1.0
    assert "command_divisor=0.1" in repr(sc.controller) and "ka=" not in repr(sc.controller)
    assert sc.to_dict()["controller"]["command_divisor"] == 0.1
    # The core's serde declaration spells it command_divisor too, with ka as its alias.
    assert sc._to_core()["controller"]["command_divisor"] == 0.1
    core = sc._to_core()
    core["controller"]["ka"] = core["controller"].pop("command_divisor")
    _core.validate(core)


def test_deprecated_controller_ka_still_works_and_warns():
    with pytest.warns(DeprecationWarning, match=r"ComputedTorque\(ka=\.\.\.\) is deprecated"):
        ctl = ar.ComputedTorque(ka=0.2)
    assert ctl == ar.ComputedTorque(command_divisor=0.2)
    with pytest.warns(DeprecationWarning, match="use controller.command_divisor"):
        assert ctl.ka == 0.2
    with pytest.warns(DeprecationWarning, match="controller.ka is deprecated") as record:
        sc = ar.Scenario().replace(**{"controller.ka": 3.0})
    assert record[0].filename == __file__  # attributed to the caller's line
    assert sc.controller.command_divisor == 3.0
    with pytest.warns(DeprecationWarning, match="controller.ka is deprecated"):
        sc = _toml("[controller]\nka = 4.0\n")
    assert sc.controller == ar.TimeDelayControl(command_divisor=4.0)
    with pytest.warns(DeprecationWarning, match="controller.ka is deprecated"):
        table = ar.sweep(ar.Scenario(duration=0.01), grid={"controller.ka": [4.0]},
                         progress=False)  # fmt: skip
    assert table["controller.command_divisor"].to_list() == [4.0]
    with pytest.raises(TypeError, match="both ka and command_divisor"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)
            ar.ModelFree(ka=1.0, command_divisor=2.0)


def test_command_divisor_range_error_uses_the_new_name():
    with pytest.raises(ar.ParameterError) as info:
        ar.TimeDelayControl(command_divisor=0.0)
    assert info.value.field == "command_divisor"
    assert str(info.value) == "command_divisor = 0 is invalid: must be finite and > 0"
    with pytest.raises(ar.ParameterError) as info:
        ar.sweep(ar.Scenario(duration=0.01), grid={"controller.command_divisor": [1.0, math.nan]},
                 progress=False)  # fmt: skip
    assert info.value.field == "controller.command_divisor" and info.value.run_id == 1


@pytest.mark.parametrize(
    "make",
    [
        lambda: ar.Wall(stiffness="stiff"),
        lambda: ar.Robot(lengths=1.0),
        lambda: ar.simulate("fig14"),
        lambda: ar.sweep("fig14", grid={"admittance.b": [1.0]}),
        lambda: ar.Scenario(robot=ar.Wall()),
        lambda: ar.TimeDelayControl(model=3),
        lambda: _core.validate({**ar.Scenario()._to_core(), "duration": "long"}),
        lambda: _core.validate({**ar.Scenario()._to_core(),
                                "sensor": {**ar.ForceSensor()._to_core(), "latency": [1]}}),
    ],
)
def test_a_wrong_type_is_a_parameter_type_error_under_the_root(make):
    """Issue #59 part 3: wrong types raised a plain TypeError outside AdmitError, from the
    Python blocks and from the core's decoder alike."""
    with pytest.raises(ar.ParameterTypeError) as info:
        make()
    assert isinstance(info.value, TypeError) and isinstance(info.value, ar.AdmitError)


def test_bad_arguments_are_under_the_root():
    sc = ar.paper.scenario("fig14").replace(duration=0.01)
    for kw in ({"grid": {"admittance.b": []}},
               {"vary": {"admittance.b": ar.Uniform(1, 2)}, "grid": {"admittance.b": [1.0]}},
               {"grid": {"admittance.b": [400.0]}, "chunk_size": 0}):
        with pytest.raises(ar.AdmitError) as info:
            ar.sweep(sc, progress=False, **kw)
        assert isinstance(info.value, ValueError)


def test_a_batch_keeps_each_errors_class_and_attributes():
    """A run of a batch that names no field keeps its class and suggestions (it became a
    plain TypeError), its message led by the run's index."""
    good = ar.Scenario(duration=0.01)._to_core()
    bad = {**good, "wall": {**good["wall"], "stifness": 1.0}}
    with pytest.raises(ar.UnknownParameterError) as info:
        _core.simulate_batch([good, bad], 1, False, False)
    assert str(info.value).startswith("scenario 1: ") and "stiffness" in info.value.suggestions
