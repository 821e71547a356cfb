"""benchmarks/time_to_competence.py: its competence rule, its plain checkpoints, its judge
and its bare-torch peer, without training (the training is the Oracle's, tested apart)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from hola_ray.methods.config import RunConfig
from hola_ray.policies.learned import MLPPolicy, random_export

_spec = importlib.util.spec_from_file_location(
    "time_to_competence", Path(__file__).parents[2] / "benchmarks" / "time_to_competence.py"
)
ttc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ttc)

CONFIG = RunConfig.from_dict(
    {
        "method": "sp",
        "env": {"n_pursuers": 3, "n_evaders": 1, "horizon": 80},
        "oracle": {"hidden": [16, 16], "train_batch": 512, "minibatch": 128, "epochs": 2},
    }
)


@pytest.mark.parametrize(
    "success, collision, verdict",
    [(0.85, 0.15, True), (0.9, 0.1, True), (0.849, 0.1, False), (0.95, 0.151, False)],
)
def test_competence_is_both_thresholds_inclusive(success, collision, verdict):
    assert ttc.competent({"success": success, "collision": collision}) is verdict


def test_checkpoints_round_trip_as_plain_arrays_and_refuse_pickles(tmp_path):
    state = {"a.weight": np.arange(6, dtype=np.float32).reshape(2, 3), "a.bias": np.ones(2)}
    ttc.save_state(tmp_path / "s.npz", state)
    back = ttc.load_state(tmp_path / "s.npz")
    assert back.keys() == state.keys()
    for k in state:
        np.testing.assert_array_equal(back[k], state[k])
    np.savez(tmp_path / "bad.npz", x=np.array([{"code": 1}], dtype=object))
    with pytest.raises(ValueError, match="pickle"):
        ttc.load_state(tmp_path / "bad.npz")


def test_the_judge_plays_the_exported_learner_as_its_copies_on_fixed_seeds():
    export = random_export(CONFIG.env.obs_dim, hidden=(16, 16), seed=0)
    judge = ttc.Judge(CONFIG, episodes=20)
    first, again = judge(export), judge(export)
    assert first == again  # the same seeds every time
    assert 0.0 <= first["success"] <= 1.0 and 0.0 <= first["collision"] <= 1.0
    other = ttc.Judge(CONFIG, episodes=20, partners=[MLPPolicy(CONFIG.env, export)] * 2)
    beside = other(export)
    assert set(beside) == {"success", "collision", "length", "own_crash"}


def test_the_bare_torch_peer_runs_the_configs_minibatches_and_times_them():
    seconds = ttc.bare_torch_update(CONFIG, rows=1000, repeats=1)
    assert seconds > 0.0
