"""The command line prints valid JSON, a table on request, and documented exit codes."""

from __future__ import annotations

import json

import pytest
from admit_rs import cli

BOUNCING = (
    "duration = 3.0\n[wall]\nstiffness = 700000.0\n"
    '[admittance]\nkind = "admittance"\nb = 200.0\nka = 1.0\n'
)


def test_run_prints_valid_json_without_nan(tmp_path, capsys):
    toml = tmp_path / "sc.toml"
    toml.write_text('duration = 0.5\n[admittance]\nkind = "admittance"\nb = 400.0\nka = 1.0\n')
    # A 0.5 s run has no window after 1 s: not assessed (exit 3), NaN metrics as null.
    assert cli.main(["run", str(toml)]) == 3
    out = capsys.readouterr().out
    assert "NaN" not in out and "Infinity" not in out
    data = json.loads(out)
    assert data["metrics"]["contact_loss"] is None and data["metrics"]["stable"] is None
    assert data["metrics"]["force_peak"] > 0
    assert data["stable"] is None and data["diverged"] is False
    assert data["verdict"].startswith("not assessed: only 0 s of the run after t = 1 s")


def test_unstable_run_exits_3_with_its_verdict(tmp_path, capsys):
    toml = tmp_path / "bounce.toml"
    toml.write_text(BOUNCING)
    assert cli.main(["run", str(toml)]) == 3
    data = json.loads(capsys.readouterr().out)
    assert data["stable"] is False and data["diverged"] is False
    assert data["verdict"].startswith("unstable: loss of contact: f = 0 in")


def test_table_format_has_units(tmp_path, capsys):
    toml = tmp_path / "bounce.toml"
    toml.write_text(BOUNCING)
    assert cli.main(["run", str(toml), "--format", "table"]) == 3
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("NOT STABLE: unstable: loss of contact")
    assert lines[1].startswith("verdict") and "loss of contact" in lines[1]
    assert lines[-1].startswith("* the run is not stable")
    row = {line.split()[0]: line.split()[1:] for line in lines[2:-1]}
    assert row["force_peak"][1] == "N" and row["z_rms_error"][1] == "m"
    assert row["contact_loss"][1:] == ["fraction", "(0–1)"]
    assert row["stable"] == ["False"]


def test_help_documents_exit_codes(capsys):
    with pytest.raises(SystemExit) as info:
        cli.main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for code in ("0 ", "2 ", "3 ", "130"):
        assert f"\n  {code}" in out


def test_tune_verb_reports_gains_and_verification(capsys):
    argv = ["tune", "fig14", "--vary", "admittance.b=100:3000", "--vary", "admittance.ka=0.2:5",
            "--over", "wall.stiffness=1e4:1e5", "--max-overshoot", "15",
            "--verify-duration", "4", "--format", "json"]  # fmt: skip
    assert cli.main(argv) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["verified"] is True
    assert set(data["gains"]) == {"admittance.b", "admittance.ka"}
    assert len(data["verification"]) == 3 and all(v["stable"] for v in data["verification"])


def test_tune_table_fits_an_80_column_terminal(capsys, monkeypatch):
    """Issue #53, item 20: the table format wrapped numbers and verdicts mid-word at 80
    columns; now every line fits the terminal and each point says its verdicts whole."""
    monkeypatch.setenv("COLUMNS", "80")
    argv = ["tune", "fig14", "--vary", "admittance.b=100:3000", "--over",
            "wall.stiffness=1e4:1e5", "--verify-duration", "2", "--format", "table"]  # fmt: skip
    cli.main(argv)
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert max(len(line) for line in lines) <= 80, out
    assert sum(line.startswith("  corner: wall.stiffness = ") for line in lines) == 2, out
    assert any(line.startswith("  centre: wall.stiffness = 3.162e+04") for line in lines), out
    assert out.count("motion held: ") >= 3 and out.count("with motion: ") >= 3, out
    assert lines[0].startswith("gains: admittance.b = ")


def test_tune_verb_bad_input_exits_2(capsys):
    with pytest.raises(SystemExit) as e:
        cli.main(["tune", "fig14", "--vary", "admittance.b=100", "--over", "wall.stiffness=1:2"])
    assert e.value.code == 2
    assert cli.main(["tune", "fig14", "--vary", "admittance.bb=1:2",
                     "--over", "wall.stiffness=1e4:1e5"]) == 2  # fmt: skip
    assert "no such parameter" in capsys.readouterr().err


def test_run_a_urdf_arm_with_a_path_relative_to_the_toml(tmp_path, capsys):
    from pathlib import Path

    data = Path(__file__).resolve().parent.parent / "examples" / "data"
    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "three_link.urdf").write_text((data / "three_link.urdf").read_text())
    toml = tmp_path / "sc.toml"
    toml.write_text(
        'duration = 3.0\n[robot]\nkind = "urdf"\npath = "arms/three_link.urdf"\n'
        'tip_link = "tip"\nviscous_friction = 3.0\ncoulomb_friction = 5.0\n'
        "q0 = [0.0, 0.7853981633974483, -0.7853981633974483]\n"
    )
    assert cli.main(["run", str(toml)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["stable"] and out["metrics"]["joint_limit_violation"] == 0.0


def test_run_and_tune_take_a_figure_or_a_toml_with_a_relative_urdf(tmp_path, monkeypatch):
    """Issue #53, item 14: `admit-rs run fig14` answered "No such file or directory", and
    `tune` read a URDF path relative to the current folder, not to the TOML file."""
    from pathlib import Path

    import admit_rs as ar

    assert cli._scenario_argument("fig14") == ar.paper.scenario("fig14")
    assert cli._scenario_argument("9:2") == ar.paper.scenarios("fig9")[1]
    with pytest.raises(ar.ArgumentError, match="curves 1 to"):
        cli._scenario_argument("fig9:7")
    with pytest.raises(KeyError, match="fig14"):
        cli._scenario_argument("fig41")
    data = Path(__file__).resolve().parent.parent / "examples" / "data"
    (tmp_path / "arms").mkdir()
    (tmp_path / "arms" / "three_link.urdf").write_text((data / "three_link.urdf").read_text())
    (tmp_path / "sc.toml").write_text(
        '[robot]\nkind = "urdf"\npath = "arms/three_link.urdf"\ntip_link = "tip"\n'
    )
    monkeypatch.chdir(Path(__file__).resolve().parent)  # elsewhere than the TOML's folder
    arm = cli._scenario_argument(str(tmp_path / "sc.toml")).robot
    assert isinstance(arm, ar.UrdfArm) and Path(arm.path) == tmp_path / "arms/three_link.urdf"


def test_run_a_paper_figure_by_name(capsys):
    assert cli.main(["run", "fig14", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["stable"] is True
