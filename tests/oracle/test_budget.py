"""Budgets on the learner's own experience: at `oracle.budget: learner_samples` the
self-play learner (every seat) and a single learner (one seat) consume the same number of
their own transitions and take the same number of gradient steps; at env_steps self-play's
learner gets about n_p times the data. Counted from what the learner consumed, and checked
against what the env runners sampled for it. One Ray session for the module."""

from __future__ import annotations

import pytest

from hola_ray.methods.config import RunConfig
from hola_ray.oracle import LEARNER

BUDGET = 2400
BATCH = 600


def config(method: str, budget: str) -> RunConfig:
    return RunConfig.from_dict(
        {
            "method": method,
            "env": {"horizon": 60},
            "oracle": {
                "hidden": [16, 16],
                "train_batch": BATCH,
                "minibatch": 200,
                "epochs": 2,
                "envs_per_runner": 6,
                "env_runners": 0,  # the counts do not depend on where sampling runs
                "env_steps": BUDGET,
                "budget": budget,
            },
            "population": {"max_size": 3, "initial_size": 3, "top_m": 1},
            "validation": {"pool": "none"},
        }
    )


def train(method: str, budget: str):
    run_config = config(method, budget)
    oracle = run_config.strategy.make_oracle(run_config)
    try:
        stats = oracle.train(BUDGET, progress=False)
        sampled = oracle.algo.metrics.peek(
            ("env_runners", "num_module_steps_sampled_lifetime", LEARNER)
        )
    finally:
        oracle.stop()
    return stats, int(sampled)


@pytest.fixture(scope="module")
def runs(ray_session):
    return {(m, b): train(m, b) for m in ("sp", "hola") for b in ("learner_samples", "env_steps")}


def test_equal_learner_samples_and_gradient_steps_at_the_learner_samples_budget(runs):
    sp, sp_sampled = runs[("sp", "learner_samples")]
    one, one_sampled = runs[("hola", "learner_samples")]
    for stats, sampled in ((sp, sp_sampled), (one, one_sampled)):
        assert stats.learner_samples == sampled  # every sampled learner step was consumed
        assert BUDGET <= stats.learner_samples < BUDGET + BATCH  # stops within one batch
    # self-play's batch spans a third of the env steps: the same data from fewer steps
    assert sp.env_steps < 0.5 * one.env_steps
    # a PPO update covers its batch `epochs` times in minibatches: equal batches, equal steps
    assert abs(sp.gradient_steps - one.gradient_steps) <= 2 * 2  # one batch's worth at most


def test_at_the_env_steps_budget_self_play_learns_from_every_seat(runs):
    sp, _ = runs[("sp", "env_steps")]
    one, _ = runs[("hola", "env_steps")]
    assert sp.env_steps >= BUDGET and one.env_steps >= BUDGET
    assert sp.learner_samples > 2 * one.learner_samples  # n_p = 3 seats against one
