"""Export to ros2_controllers' admittance_controller: numbers read back with a YAML parser."""

from __future__ import annotations

import math

import admit_rs as ar
import pytest
import yaml


def _params(path):
    data = yaml.safe_load(path.read_text())
    assert list(data) == ["admittance_controller"]
    return data["admittance_controller"]["ros__parameters"]


def test_scheme1_maps_mass_damping_ratio_stiffness_axes_and_filter(tmp_path):
    sc = ar.paper.scenario("fig8")  # CT + Scheme 1: m = 1, b = 800, k = 400, k_a = 0.1
    adm = sc.admittance
    assert (adm.m, adm.b, adm.k, adm.ka) == (1.0, 800.0, 400.0, 0.1)
    path = tmp_path / "admittance.yaml"
    text = ar.export.ros2_admittance(sc, path)
    assert path.read_text() == text
    p = _params(path)
    a = p["admittance"]
    assert a["selected_axes"] == [True, False, False, False, False, False]
    assert a["mass"] == [pytest.approx(10.0)] * 6  # m / k_a
    assert a["stiffness"] == [pytest.approx(4000.0)] * 6  # k / k_a
    assert a["damping_ratio"] == [pytest.approx(20.0)] * 6  # b / (2 sqrt(m k))
    assert p["ft_sensor"]["filter_coefficient"] == 1.0
    # Every double is written as a float (the controller rejects integers there).
    assert all(isinstance(v, float) for v in a["mass"] + a["stiffness"] + a["damping_ratio"])
    # The controller's own damping, D = zeta * 2 sqrt(M K), is the filter's b / k_a.
    damping = a["damping_ratio"][0] * 2 * math.sqrt(a["mass"][0] * a["stiffness"][0])
    assert damping == pytest.approx(adm.b / adm.ka)


def test_other_gains_and_options(tmp_path):
    sc = ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(m=2.0, b=100.0, k=50.0, ka=2.0))
    text = ar.export.ros2_admittance(sc, tmp_path / "a.yaml", controller_name="force_ctl",
                                     filter_coefficient=None)  # fmt: skip
    data = yaml.safe_load(text)
    p = data["force_ctl"]["ros__parameters"]
    assert "ft_sensor" not in p
    assert p["admittance"]["mass"][0] == pytest.approx(1.0)
    assert p["admittance"]["stiffness"][0] == pytest.approx(25.0)
    assert p["admittance"]["damping_ratio"][0] == pytest.approx(100.0 / (2 * math.sqrt(100.0)))
    tiny = ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(m=1.0, b=1e-5, k=1.0, ka=1.0))
    # 5e-06 must stay a float for a YAML 1.1 reader too: a dot in the mantissa.
    assert "damping_ratio: [5.0e-06," in ar.export.ros2_admittance(tiny, None)


def test_scheme2_is_refused_with_the_nearest_faithful_alternative(tmp_path):
    sc = ar.paper.scenario("fig14")  # TDC + Scheme 2: k = 0, k_a = 1, k_e = 30 000
    path = tmp_path / "a.yaml"
    with pytest.raises(ar.ExportError) as info:
        ar.export.ros2_admittance(sc, path)
    msg = str(info.value)
    assert "Scheme 2 (admittance.k = 0) cannot be written" in msg
    assert "damping_ratio * 2 * sqrt(M * K), which is 0" in msg
    assert "admittance.k = 303 N/m keeps the steady-state force error at 1 % of f_d" in msg
    assert isinstance(info.value, ar.AdmitError) and isinstance(info.value, ValueError)
    assert not path.exists()  # nothing written, not even a different controller
    # The suggested alternative exports, and in simulation it costs less than the 1 % of
    # f_d (0.1 N) of extra steady-state force error that the message promises.
    alt = sc.replace(**{"admittance.k": 303.0303})
    assert _params_text(ar.export.ros2_admittance(alt, None))["stiffness"][0] == (
        pytest.approx(303.0303)
    )
    extra = ar.simulate(alt).metrics["force_ss_error"] - ar.simulate(sc).metrics["force_ss_error"]
    assert 0.0 < extra < 0.1


def _params_text(text):
    return yaml.safe_load(text)["admittance_controller"]["ros__parameters"]["admittance"]


def test_force_loops_without_an_equivalent_are_refused():
    with pytest.raises(ar.ExportError, match="eq. \\(20\\) impedance reference"):
        ar.export.ros2_admittance(ar.Scenario(admittance=ar.ImpedanceReference()), None)
    with pytest.raises(ar.ExportError, match="no force loop"):
        ar.export.ros2_admittance(ar.paper.scenario("fig5"), None)
    with pytest.raises(ar.ExportError, match="admittance.ka = 0"):
        ar.export.ros2_admittance(
            ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(ka=0.0)), None
        )
    with pytest.raises(ar.ExportError, match="outside admittance_controller's bounds"):
        ar.export.ros2_admittance(
            ar.Scenario(admittance=ar.AdmittanceFilter.scheme1(k=1e9, ka=1.0)), None
        )
