"""The Oracle's PPO settings as RLlib reads them."""

from __future__ import annotations

import pytest
from ray.rllib.utils.schedules.scheduler import Scheduler

from hola_ray.config.oracle import OracleConfig


def test_the_learning_rate_decays_linearly_as_rllib_reads_a_schedule():
    assert OracleConfig(lr=1e-3).lr_schedule == 1e-3  # no decay: the constant
    config = OracleConfig(lr=1e-3, lr_decay_env_steps=1000, lr_final=1e-4)
    schedule = Scheduler(fixed_value_or_schedule=config.lr_schedule, framework="torch")
    # halfway: 1e-3 + (1e-4 − 1e-3) · 0.5 = 5.5e-4; past the end it stays at lr_final
    assert float(schedule.update(timestep=500)) == pytest.approx(5.5e-4)
    assert float(schedule.update(timestep=5000)) == pytest.approx(1e-4)
