"""Shared fixtures: the default scenario and a nearly frozen one for hand-worked geometry."""

from __future__ import annotations

import dataclasses

import pytest

from hola_ray.env import PursuitConfig


@pytest.fixture(scope="session")
def config() -> PursuitConfig:
    return PursuitConfig()


@pytest.fixture(scope="session")
def frozen_config() -> PursuitConfig:
    """dt = 1e-6 s: drones move at most 6e-7 m per step, so set distances hold to 1e-6."""
    return dataclasses.replace(PursuitConfig(), dt=1e-6)
