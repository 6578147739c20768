"""One schema (SPEC §14): every Python block against the Rust declaration of its block.

The Rust structs are declared once with serde; ``_core.schema()`` is their JSON schema
(field names, docs from the doc comments) and ``_core.defaults()`` their ``Default``
serialised. A field added on one side only, a default or a doc that differs, fails here.
"""

import dataclasses

import admit_rs as ar
import pytest
from admit_rs import _core, config

SCHEMA = _core.schema()
DEFAULTS = _core.defaults()
WITHOUT_RUST_DEFAULTS = {"impedance", "step", "sine", "sampled"}
"""Blocks with no Rust ``Default`` (a signal's defaults depend on what it drives; the
impedance reference has no paper preset): their Python defaults are the only ones."""


def _key(cls):
    """The block's key in the schema: its kind tag, else the block it checks as."""
    return "scenario" if cls is ar.Scenario else (cls._kind or cls._check)


BLOCKS = {_key(cls): cls for cls in config._BLOCKS}


def _plain(v):
    if isinstance(v, config._Block):
        return _plain(v._to_core())
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items() if k != "label"}
    return v


def _python_fields(cls):
    # Python-only: a scenario's free-text label, the file a URDF was read from.
    return [f for f in dataclasses.fields(cls) if f.name not in cls._PYTHON_ONLY]


def _doc(cls, name):
    return next((config._DOCS[c.__name__][name] for c in cls.__mro__
                 if name in config._DOCS.get(c.__name__, {})), "")  # fmt: skip


def test_every_block_is_on_both_sides():
    assert {"sensor", "actuator"} <= set(BLOCKS)  # ForceSensor and Actuator are blocks too
    assert set(BLOCKS) == set(SCHEMA), set(BLOCKS) ^ set(SCHEMA)
    assert set(DEFAULTS) == set(SCHEMA) - WITHOUT_RUST_DEFAULTS


@pytest.mark.parametrize("key", sorted(SCHEMA))
def test_fields_and_docs_equal_the_rust_declaration(key):
    cls = BLOCKS[key]
    props = {k: v for k, v in SCHEMA[key]["properties"].items() if k != "kind"}
    names = [f.name for f in _python_fields(cls)]
    assert set(names) == set(props), (key, set(names) ^ set(props))
    for name in names:
        rust = " ".join(props[name].get("description", "").split())
        assert rust, f"{key}.{name} has no doc in Rust"
        python = _doc(cls, name)
        assert python == rust, f"{key}.{name}:\n  python: {python}\n  rust:   {rust}"


@pytest.mark.parametrize("key", sorted(DEFAULTS))
def test_defaults_equal_the_rust_default(key):
    cls = BLOCKS[key]
    rust = {k: v for k, v in DEFAULTS[key].items() if k != "kind"}
    python = {}
    for f in _python_fields(cls):
        if f.default is not dataclasses.MISSING:
            python[f.name] = _plain(f.default)
        else:
            python[f.name] = _plain(f.default_factory())  # type: ignore[misc]
    assert set(python) == set(rust), (key, set(python) ^ set(rust))
    for name, value in rust.items():
        assert python[name] == value, f"{key}.{name}: {python[name]!r} != {value!r}"
    if "kind" in DEFAULTS[key]:
        assert DEFAULTS[key]["kind"] == cls._kind


def test_the_default_scenario_is_the_rust_default():
    assert _plain(ar.Scenario()) == DEFAULTS["scenario"]


def test_tagged_blocks_carry_their_kind():
    for key, schema in SCHEMA.items():
        kind = schema["properties"].get("kind", {}).get("const")
        if kind is not None:
            assert BLOCKS[key]._kind == kind == key


# -- the core decodes by the declaration, with errors as good as the blocks' ---------------


def _core_error(change):
    core = ar.Scenario()._to_core()
    change(core)
    with pytest.raises(Exception) as info:
        _core.validate(core)
    return info.value


def test_core_unknown_keys_name_the_closest_valid_ones():
    err = _core_error(lambda c: c["wall"].update(stifness=1.0))
    assert isinstance(err, ar.UnknownParameterError)
    assert str(err).startswith("wall: unknown key 'stifness'") and "stiffness" in err.suggestions
    err = _core_error(lambda c: c["controller"].update(kdd=1.0))  # a tagged, flattened block
    assert isinstance(err, ar.UnknownParameterError) and "kd" in err.suggestions
    err = _core_error(lambda c: c.update(duraton=1.0))
    assert str(err).startswith("scenario: unknown key 'duraton'; did you mean duration")


@pytest.mark.parametrize(
    ("change", "field", "allowed"),
    [
        (lambda c: c["wall"].update(model="x"), "wall.model", "'kelvin_voigt', 'hunt_crossley'"),
        (lambda c: c["robot"].update(mass_model="x"), "robot.mass_model", "'rod', 'point'"),
        (lambda c: c["controller"].update(law="x"), "controller.law", "'jacobian_transpose'"),
        (lambda c: c["controller"].update(kind="x"), "controller.kind", "'computed_torque'"),
        (lambda c: c["sensor"].update(latency=2.5), "sensor.latency", "from 0 to 100000"),
        (lambda c: c.update(substeps=0), "substeps", "from 1 to"),
        (lambda c: c["controller"].update(inertia=[[1.0, 2.0]]), "controller.inertia", "n×n"),
    ],
)
def test_core_bad_values_are_parameter_errors_naming_the_field(change, field, allowed):
    err = _core_error(change)
    assert type(err) is ar.ParameterError, err
    assert err.field == field and allowed in err.allowed, (err.field, err.allowed)
    assert str(err).startswith(f"{field} = ")


def test_core_wrong_types_are_type_errors():
    err = _core_error(lambda c: c["wall"].update(stiffness="a"))
    assert type(err) is TypeError and str(err) == "wall.stiffness must be a number, got str"
    err = _core_error(lambda c: c["controller"].update(kp=True))
    assert type(err) is TypeError and "must be a number, got a bool" in str(err)


def test_numpy_scalars_cross_as_numbers():
    import numpy as np

    sc = ar.Scenario(duration=0.01).replace(**{"sensor.latency": np.int64(2)})
    assert sc._to_core()["sensor"]["latency"] == 2
    ar.simulate(sc)
