"""The optional peers of benches/sweep_compare.py (JAX) and benches/panda_mujoco.py (MuJoCo)
import without their peer, and agree with admit_rs on a tiny case when it is installed."""

from __future__ import annotations

import sys
from pathlib import Path

import admit_rs as ar
import numpy as np
import pytest

BENCHES = Path(__file__).resolve().parent.parent / "benches"
sys.path.insert(0, str(BENCHES))

import jax_peer  # noqa: E402
import panda_mujoco  # noqa: E402
import peers  # noqa: E402


def test_bench_modules_import_without_their_peer():
    assert isinstance(jax_peer.HAVE_JAX, bool)
    assert isinstance(panda_mujoco.HAVE_MUJOCO, bool)


@pytest.mark.skipif(not jax_peer.HAVE_JAX, reason="jax not installed")
def test_jax_peer_agrees_with_admit_rs_on_a_short_sweep():
    base = ar.paper.scenario("fig19").replace(duration=1.2)
    vary = {"wall.stiffness": ar.LogUniform(1e4, 1e5), "wall.position_error": ar.Uniform(0, 0.01)}
    table = ar.sweep(base, vary=vary, samples=4, seed=0, threads=1, progress=False)
    c = peers.Fig14(duration=1.2, position_error=0.01)
    wall = peers.setup(c).wall
    sweep = jax_peer.build(c, 1)
    peak, rms, _, diverged = (
        np.asarray(a)
        for a in sweep(
            table["wall.stiffness"].to_numpy(), wall + table["wall.position_error"].to_numpy()
        )
    )
    assert not diverged.any()
    for name, ours in [("force_peak", peak), ("force_rms_error", rms)]:
        ref = table[name].to_numpy()
        assert np.max(np.abs(ours - ref) / np.abs(ref)) <= 1e-9, name


@pytest.mark.skipif(not panda_mujoco.HAVE_MUJOCO, reason="mujoco not installed")
def test_mujoco_peer_agrees_with_admit_rs_on_a_short_panda_run():
    sc = panda_mujoco.scenario(0.05, 1)
    panda_mujoco.check_scenario(sc)
    peer = panda_mujoco.Peer(sc, 1e-3, "actuator")
    assert panda_mujoco.check_model(peer, sc) < 1e-12
    forces, _, _ = peer.run(0.05)
    f_ar = ar.simulate(sc).trace["f"].to_numpy()
    assert forces.max() > 1.0  # in contact: the comparison means something
    assert np.max(np.abs(forces - f_ar)) < 1e-9
