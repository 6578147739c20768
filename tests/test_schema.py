"""One declaration (SPEC §14): every Python block's fields are written from the Rust one.

The Rust structs are declared once with serde and schemars; ``_core.schema()`` is their JSON
schema (field names, types, docs from the doc comments, defaults), ``_core.defaults()`` their
``Default`` serialised and ``_core.registry()`` the families and kinds. ``admit_rs._codegen``
writes each block's fields from them; a field changed on the Rust side fails here until the
generator has been run again.
"""

import dataclasses

import admit_rs as ar
import pytest
from admit_rs import _codegen, _core, _registry, config

SCHEMA = _core.schema()
DEFAULTS = _core.defaults()
DECLARATION = _codegen.Declaration.from_core()
BLOCKS = {cls._key: cls for cls in config._BLOCKS}


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


@pytest.mark.parametrize("path", _codegen.files(), ids=lambda p: p.name)
def test_generated_fields_are_the_rust_declaration(path):
    text = path.read_text(encoding="utf-8")
    assert _codegen.generate(text, DECLARATION) == text, (
        f"{path.name} differs from the Rust declaration: run python python/admit_rs/_codegen.py"
    )


def test_the_generator_notices_a_changed_declaration():
    """A field added, a default or a doc changed in Rust: the region written anew differs."""
    schema = {k: dict(v) for k, v in SCHEMA.items()}
    wall = dict(schema["wall"]["properties"])
    wall["stiffness"] = {**wall["stiffness"], "description": "Changed [N/m]."}
    wall["new_field"] = {"type": "number", "description": "A new field [m]."}
    schema["wall"] = {**schema["wall"], "properties": wall}
    defaults = {k: dict(v) for k, v in DEFAULTS.items()}
    defaults["wall"]["new_field"] = 0.5
    defaults["sensor"]["latency"] = 3
    changed_decl = _codegen.Declaration(schema, defaults, DECLARATION.registry)
    texts = {p.name: p.read_text(encoding="utf-8") for p in _codegen.files()}
    changed = {name: _codegen.generate(text, changed_decl) for name, text in texts.items()}
    new = {line for name, text in texts.items()
           for line in set(changed[name].splitlines()) - set(text.splitlines())}  # fmt: skip
    assert "    new_field: float = 0.5" in new
    assert '    """A new field [m]."""' in new
    assert "    latency: int = 3" in new
    # The shared surface fields differ between the blocks now: stiffness moves out of
    # the shared region into each surface's own.
    assert "    stiffness: float = 30000.0" in changed["surface.py"].split('fields of "sphere"')[1]


def test_every_kind_has_its_class_and_region():
    regions = set()
    for path in _codegen.files():
        regions |= set(_codegen.keys_in(path.read_text(encoding="utf-8")))
    kinds = [k for family in _registry.FAMILIES.values() for k in family]
    assert {k.cls for k in kinds} == set(config._CLASSES), "a kind without its class"
    assert {k.key for k in kinds} == regions == set(BLOCKS) == set(SCHEMA) == set(DEFAULTS)
    for k in kinds:
        cls = config._CLASSES[k.cls]
        assert (cls._key, cls._kind, cls._check) == (k.key, k.tag, k.family)


@pytest.mark.parametrize("key", sorted(SCHEMA))
def test_fields_and_docs_equal_the_rust_declaration(key):
    cls = BLOCKS[key]
    props = {k: v for k, v in SCHEMA[key]["properties"].items() if k != "kind"}
    names = [f.name for f in _python_fields(cls)]
    keywords = [f.name for f in _python_fields(cls) if f.kw_only]  # positional ones lead
    assert keywords == [n for n in props if n in keywords]  # the declaration's order
    assert set(names) == set(props), (key, set(names) ^ set(props))
    for name in names:
        rust = " ".join(props[name].get("description", "").split())
        assert rust, f"{key}.{name} has no doc in Rust"
        assert _doc(cls, name) == rust, f"{key}.{name}"


@pytest.mark.parametrize("key", sorted(DEFAULTS))
def test_defaults_equal_the_rust_default(key):
    cls = BLOCKS[key]
    rust = {k: v for k, v in DEFAULTS[key].items() if k != "kind"}
    python = _plain(cls()) if key != "urdf" else None
    if python is not None:
        python.pop("kind", None)
        assert python == rust
    if "kind" in DEFAULTS[key]:
        assert DEFAULTS[key]["kind"] == (cls._kind or cls._core_kind)


def test_the_default_scenario_is_the_rust_default():
    assert _plain(ar.Scenario()) == DEFAULTS["scenario"]


def test_scenario_fields_hold_their_registry_family():
    assert config._UNIONS["wall"] == (ar.Wall, ar.Sphere, ar.Cylinder, ar.HeightField,
                                      type(None))  # fmt: skip
    assert config._UNIONS["controller"] == (ar.ComputedTorque, ar.ModelFree,
                                            ar.TimeDelayControl)  # fmt: skip
    assert config._UNIONS["sensor"] == (ar.ForceSensor,)
    assert config._slot_types("model") == (ar.ModelError,)


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
    assert type(err) is ar.ParameterTypeError
    assert str(err) == "wall.stiffness must be a number, got str"
    err = _core_error(lambda c: c["controller"].update(kp=True))
    assert type(err) is ar.ParameterTypeError and "must be a number, got a bool" in str(err)


def test_numpy_scalars_cross_as_numbers():
    import numpy as np

    sc = ar.Scenario(duration=0.01).replace(**{"sensor.latency": np.int64(2)})
    assert sc._to_core()["sensor"]["latency"] == 2
    ar.simulate(sc)


def test_sequences_take_the_declared_tuple_shape():
    """No block converts its tuple fields by hand any more where the declaration suffices:
    ``Sampled`` has no conversion of its own, yet lists and arrays become tuples of floats
    (so the block hashes and compares by value), and an int beyond the float range is a
    ParameterError naming the field (it was an OverflowError)."""
    import numpy as np

    s = ar.Sampled(times=np.arange(3), values=[1, 2, 3.5])
    assert s.times == (0.0, 1.0, 2.0) and s.values == (1.0, 2.0, 3.5)
    assert all(type(v) is float for v in s.times + s.values)
    assert hash(s) == hash(ar.Sampled(times=(0, 1, 2), values=(1, 2, 3.5)))
    assert "__post_init__" not in vars(ar.Sampled)
    with pytest.raises(ar.ParameterError) as info:
        ar.Sampled(times=(0.0,), values=[10**400])
    assert info.value.field == "values" and info.value.allowed == "finite numbers"
