"""The realism example runs and says what docs/realism.md says it does."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_realism_example(tmp_path):
    spec = importlib.util.spec_from_file_location("realism", ROOT / "examples" / "realism.py")
    assert spec and spec.loader
    realism = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(realism)
    table = realism.main(tmp_path)
    rows = {r["case"]: r for r in table.iter_rows(named=True)}
    # A 40 N·m joint 2 cannot hold the arm: saturated almost always, not stable.
    assert rows["torque limits"]["torque_saturation"] > 0.99
    assert not rows["torque limits"]["stable"]
    # 60/60/20 N·m clips only the transient; everything else stays stable and close.
    for case in ("ideal (paper)", "sensor", "damped wall", "limits 60/60/20", "all, 60/60/20"):
        assert rows[case]["stable"], case
        assert abs(rows[case]["force_peak"] - rows["ideal (paper)"]["force_peak"]) < 0.3
    assert rows["sensor"]["overshoot_pct"] > rows["ideal (paper)"]["overshoot_pct"]
    assert (tmp_path / "realism.png").stat().st_size > 10_000
    # The committed table is this table.
    assert (tmp_path / "realism.md").read_text() == (ROOT / "docs/realism/realism.md").read_text()


def test_arms_example(tmp_path):
    spec = importlib.util.spec_from_file_location("arms", ROOT / "examples" / "arms.py")
    assert spec and spec.loader
    arms = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(arms)
    tables = arms.main(tmp_path)
    runs = tables["runs"]
    assert runs["stable"].all()
    assert (runs["force_ss_error"].abs() < 0.05).all()
    assert (runs["orientation_error [rad]"] < 1e-3).all()
    assert (runs["joint_limit_violation"] == 0).all()
    sweep = tables["sweep"]
    assert sweep["stable"].all()
    assert sweep["overshoot_pct"].is_sorted()  # overshoot grows with k_e, as in fig. 15
    assert (tmp_path / "arms.png").stat().st_size > 10_000
    assert (tmp_path / "arms.md").read_text() == (ROOT / "docs/arms/arms.md").read_text()
