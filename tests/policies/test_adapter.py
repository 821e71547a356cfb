"""`ScenarioAdapter`: a policy trained for one team reading another's observation, by hand
on observations and on whole episodes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.rollout import rollout
from hola_ray.policies.adapter import ScenarioAdapter, fitted, trained_scenario
from hola_ray.policies.base import Policy
from hola_ray.policies.learned import MLPPolicy, random_export


class Echo(Policy):
    """Records what it was shown."""

    name = "echo"

    def act(self, obs: np.ndarray) -> np.ndarray:
        self.seen = self._check(obs).copy()
        return np.full(obs.shape[0], 0.5)


def shown(config: PursuitConfig, trained: PursuitConfig, obs: np.ndarray) -> np.ndarray:
    echo = Echo(trained)
    fitted(config, echo).act(obs[None].astype(np.float32))
    return echo.seen[0]


def test_more_teammates_and_evaders_than_it_has_slots_for_it_sees_the_nearest():
    """Trained 3 vs 1 with headings, in 5 vs 2: it sees the nearer evader (the farther one
    is dropped) and the two nearest teammates, in seat order, with their headings."""
    config = PursuitConfig(n_pursuers=5, n_evaders=2, observe_headings=True)
    trained = trained_scenario(config, 3, 1)
    evaders = [1.2, 0.1, 0.2, 0.4, 0.3, 0.5]  # evader 1 nearer
    obstacle = [0.7, -0.2]
    mates = [0.9, 0.1, 0.3, 0.2, 2.0, 0.0, 0.5, -0.4]  # mates 1 and 3 nearest; 2 unobserved
    own = [0.1, 0.2, 0.0, 1.0]
    headings = [0.11, 0.22, 0.33, 0.44]
    obs = np.array(evaders + obstacle + mates + own + headings)
    seen = shown(config, trained, obs)
    expected = [0.4, 0.3, 0.5] + obstacle + [0.3, 0.2, 0.5, -0.4] + own + [0.22, 0.44]
    np.testing.assert_allclose(seen, expected, rtol=1e-6)


def test_fewer_teammates_and_evaders_read_as_unobserved_and_captured():
    """Trained 4 vs 2, in 2 vs 1: the second evader reads captured (2, 0, 0), the two
    missing teammates unobserved (2, 0)."""
    config = PursuitConfig(n_pursuers=2, n_evaders=1)
    trained = trained_scenario(config, 4, 2)
    obs = np.array([0.4, 0.3, 0.5, 0.7, -0.2, 0.6, 0.1, 0.1, 0.2, 0.0, 1.0])
    seen = shown(config, trained, obs)
    far = config.unobserved_distance
    expected = [0.4, 0.3, 0.5, far, 0, 0, 0.7, -0.2, 0.6, 0.1, far, 0, far, 0]
    np.testing.assert_allclose(seen, expected + [0.1, 0.2, 0.0, 1.0], rtol=1e-6)


def test_the_same_observation_needs_no_adapter_and_headings_must_agree():
    config = PursuitConfig()
    policy = MLPPolicy(config, random_export(config.obs_dim))
    assert fitted(config, policy) is policy
    with pytest.raises(ValueError, match="headings"):
        ScenarioAdapter(dataclasses.replace(config, observe_headings=True), policy)


def test_a_three_pursuer_learner_in_five_slots_plays_its_own_episodes():
    """A 3 vs 2 learner in the same team observed in 5 slots (two always unobserved): the
    adapter hands it back exactly its own observation, so the episodes are the same (each
    seat its own forward pass, as the adapter's is)."""
    own = PursuitConfig(n_evaders=2, horizon=300)
    slots = dataclasses.replace(own, obs_pursuers=5, obs_evaders=3)
    export = random_export(own.obs_dim, hidden=(16,), seed=3, bias_scale=0.5)
    plain = rollout(own, [MLPPolicy(own, export)] * 3, episodes=24, seed=9, batched=False)
    adapted = fitted(slots, MLPPolicy(own, export))
    assert isinstance(adapted, ScenarioAdapter)
    played = rollout(slots, [adapted] * 3, episodes=24, seed=9, batched=False)
    np.testing.assert_array_equal(played.length, plain.length)
    np.testing.assert_array_equal(played.team_return, plain.team_return)
    assert len(set(plain.length.tolist())) > 1  # episodes that end at different times
