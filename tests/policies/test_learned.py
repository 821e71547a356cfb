"""MLPPolicy without Ray: the Beta's deterministic action, the proximity features, and the
spread instrumentation that says whether a policy is still the one that was trained."""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from hola_ray.env import PursuitConfig
from hola_ray.policies.learned import FORMAT, MLPPolicy

CONFIG = PursuitConfig(n_pursuers=3, n_evaders=1)
LAYOUT = CONFIG.layout
OBS = np.random.default_rng(0).uniform(0, 1, (40, LAYOUT.dim)).astype(np.float32)


def constant_export(bias: tuple[float, float], dist: str = "beta", features=None) -> dict:
    """One linear layer with zero weights: the head outputs `bias` whatever it sees."""
    inputs = LAYOUT.dim + len((features or {}).get("indices", ()))
    export = {
        "format": FORMAT,
        "dist": dist,
        "weights": [torch.zeros(2, inputs)],
        "biases": [torch.tensor(bias, dtype=torch.float32)],
        "activation": "tanh",
        "low": 0.0,
        "high": 1.0,
    }
    return export | ({"features": features} if features else {})


def test_beta_plays_its_mean():
    # c1 = softplus(log(e² − 1)) + 1 = 3, c0 = softplus(0) + 1 = 1 + ln 2 = 1.6931;
    # mean on [0, 1] = 3 / 4.6931 = 0.63923, and the Box is [0, 1]
    policy = MLPPolicy(CONFIG, constant_export((math.log(math.e**2 - 1), 0.0)))
    np.testing.assert_allclose(policy.act(OBS), 3 / (4 + math.log(2)), rtol=1e-6)
    # equal concentrations → straight ahead
    np.testing.assert_allclose(MLPPolicy(CONFIG, constant_export((0.4, 0.4))).act(OBS), 0.5)


def test_format_1_exports_are_gaussian_means():
    export = constant_export((0.6, -1.0)) | {"format": "hola_ray.mlp/1"}
    del export["dist"]
    policy = MLPPolicy(CONFIG, export)
    assert policy.dist == "gaussian"
    np.testing.assert_allclose(policy.act(OBS), 0.8, rtol=1e-6)  # (0.6 + 1) / 2


def test_proximity_features_reach_the_network():
    """A network that reads only the first feature, exp(−gain·obstacle reading), as c1's
    input: obstacle readings 0 and 0.04 (0.2 m) give features 1 and e^{−1.333}."""
    gain = CONFIG.obs_distance_scale / 0.15
    features = {"indices": LAYOUT.proximity, "gain": gain}
    export = constant_export((0.0, 0.0), features=features)
    export["weights"][0][0, LAYOUT.dim] = 1.0
    policy = MLPPolicy(CONFIG, export)
    obs = np.zeros((2, LAYOUT.dim), np.float32)
    obs[1, LAYOUT.obstacle] = 0.04
    c1 = torch.nn.functional.softplus(torch.tensor([1.0, math.exp(-gain * 0.04)])) + 1
    c0 = 1 + math.log(2)
    np.testing.assert_allclose(policy.act(obs), (c1 / (c1 + c0)).numpy(), rtol=1e-6)
    with pytest.raises(ValueError, match="observations of size"):
        MLPPolicy(PursuitConfig(n_pursuers=3, n_evaders=2), export)


def test_spread_sees_an_exploded_gaussian_and_a_bounded_beta():
    wide = MLPPolicy(CONFIG, constant_export((0.0, 3.0), dist="gaussian")).spread(OBS)
    assert wide["std_median"] == pytest.approx(math.exp(3.0), rel=1e-5)
    # |N(0, e³)| ≥ 1 with probability 2·Φ(−e^{−3}) = 0.960
    assert wide["clipped"] == pytest.approx(0.960, abs=0.02)
    uniform = MLPPolicy(CONFIG, constant_export((-30.0, -30.0))).spread(OBS)  # c ≈ 1: uniform
    assert uniform["std_median"] == pytest.approx(1 / math.sqrt(3), rel=1e-4)
    assert uniform["clipped"] == pytest.approx(0.01, abs=0.01)  # |a| ≥ 0.99 on U(−1, 1)
    # Beta(c, c) with c = softplus(30) + 1 = 31: std 2·√(1/(4(2c + 1))) = 1/√63 on [−1, 1]
    narrow = MLPPolicy(CONFIG, constant_export((30.0, 30.0))).spread(OBS)
    assert narrow["std_median"] == pytest.approx(1 / math.sqrt(63), rel=1e-4)
    assert narrow["clipped"] == 0.0


def test_an_export_carries_its_scenario_and_loads_without_one(tmp_path):
    """A run's export says which arena it was trained in: `MLPPolicy.load(path)` rebuilds it,
    and a given scenario with other team sizes is one clear error."""
    from hola_ray.methods.config import RunConfig

    run = RunConfig.from_dict({"env": {"n_evaders": 1, "horizon": 300}, "oracle": {"hidden": [8]}})
    dim = run.env.layout.dim + len(run.oracle.model_features(run.env)["indices"])
    rng = np.random.default_rng(0)
    state = {
        "encoder.actor_encoder.net.mlp.0.weight": rng.normal(size=(8, dim)),
        "encoder.actor_encoder.net.mlp.0.bias": np.zeros(8),
        "pi.net.mlp.0.weight": rng.normal(size=(2, 8)),
        "pi.net.mlp.0.bias": np.zeros(2),
    }
    path = tmp_path / "learner.pt"
    torch.save(run.export(state), path)
    policy = MLPPolicy.load(path)
    assert policy.config == run.env and policy.config.horizon == 300
    assert MLPPolicy.load(PursuitConfig(n_evaders=1), path).config.n_evaders == 1
    with pytest.raises(ValueError, match=r"trained for 3 pursuers vs 1 evader\(s\); this "):
        MLPPolicy.load(PursuitConfig(n_evaders=2), path)
    old = tmp_path / "old.pt"
    torch.save(constant_export((0.0, 0.0)), old)
    with pytest.raises(ValueError, match=r"load it with MLPPolicy.load\(config, path\)"):
        MLPPolicy.load(old)


def test_a_stack_plays_each_actor_as_the_actor_plays_alone():
    """`MLPStack`: the rows of several actors in one batched pass, an actor with most of the
    rows cut into pieces, give each actor's own logits and actions to within the batched
    matmul's rounding."""
    from hola_ray.policies.learned import MLPStack, random_export

    actors = [
        MLPPolicy(CONFIG, random_export(LAYOUT.dim, hidden=(32, 32), seed=k)) for k in range(4)
    ]
    stack = MLPStack(actors)
    rng = np.random.default_rng(1)
    obs = rng.uniform(-1, 1, (600, LAYOUT.dim)).astype(np.float32)
    for slot in (
        rng.integers(0, 4, 600),  # balanced
        np.where(rng.uniform(size=600) < 0.7, 3, rng.integers(0, 3, 600)),  # one dominates
    ):
        logits = stack.logits(stack.with_features(torch.from_numpy(obs)), slot)
        actions = stack.act(obs, slot)
        for k, actor in enumerate(actors):
            rows = slot == k
            assert rows.any()
            torch.testing.assert_close(logits[rows], actor.logits(obs[rows]), rtol=0, atol=1e-6)
            np.testing.assert_allclose(actions[rows], actor.act(obs[rows]), rtol=0, atol=1e-6)
    with pytest.raises(ValueError, match="one layout"):
        MLPStack([actors[0], MLPPolicy(CONFIG, random_export(LAYOUT.dim, hidden=(16,)))])


def test_an_actor_trained_without_headings_reads_the_observations_first_entries():
    """An actor of the plain layout plays in a scenario that observes the teammates'
    headings as it plays the same rows without them; one of neither size is refused."""
    from hola_ray.policies.learned import random_export

    seen = PursuitConfig(n_pursuers=3, n_evaders=1, observe_headings=True)
    export = random_export(LAYOUT.dim, hidden=(16,), seed=3)
    wide = np.concatenate([OBS, np.random.default_rng(1).uniform(-1, 1, (40, 2))], axis=1)
    wide = wide.astype(np.float32)
    np.testing.assert_array_equal(
        MLPPolicy(seen, export).act(wide), MLPPolicy(CONFIG, export).act(OBS)
    )
    with pytest.raises(ValueError, match="observations of size"):
        MLPPolicy(seen, random_export(LAYOUT.dim + 1, hidden=(16,)))
