"""Run configs: the shipped YAMLs load, round-trip, and bad values fail naming the field."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from hola_ray.env.config import ConfigError
from hola_ray.methods.config import RunConfig
from hola_ray.run import DEFAULT

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def test_default_yaml_is_the_embedded_default():
    assert RunConfig.from_yaml(CONFIGS / "default.yaml") == RunConfig.from_dict(DEFAULT)


def test_paper_yaml_has_the_paper_budget():
    c = RunConfig.from_yaml(CONFIGS / "paper.yaml")
    o = c.oracle
    assert (o.env_steps, o.train_batch, o.minibatch, o.epochs) == (1_000_000, 1024, 256, 20)
    assert (o.lr, o.gae_lambda, o.vf_coef, o.entropy_coef) == (3e-4, 0.95, 1.0, 0.01)
    assert c.population.max_size == 10 and c.l == 3 and c.env.n_evaders == 2


@pytest.mark.parametrize("name", ["default.yaml", "paper.yaml", "smoke.yaml"])
def test_yaml_round_trip(name):
    c = RunConfig.from_yaml(CONFIGS / name)
    assert RunConfig.from_dict(yaml.safe_load(c.to_yaml())) == c


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"method": "hola_x"}, r"method must be one of fcp, hola, hola_r, mep, pbt, sp, uniform"),
        ({"population": {"max_size": 2}}, r"population.max_size \(the hypergraph size\)"),
        ({"oracle": {"env_steps": -5}}, r"oracle.env_steps must be an integer >= 1"),
        ({"pretrain": {"env_steps": 0}}, r"pretrain.env_steps must be an integer >= 1"),
        ({"oracle": {"minibatch": 4096}}, r"oracle.minibatch must be <= oracle.train_batch"),
        ({"population": {"initial_size": 2}}, r"population.initial_size must be in \[l = 3"),
        ({"grapher": {"episodes": 3}}, r"unknown key\(s\) grapher.episodes"),
        ({"generations": -1}, r"generations must be an integer >= 0"),
        ({"pretrain": {"alpha": 2.0}}, r"pretrain.alpha must be in \[0, 1\]"),
    ],
)
def test_bad_values_name_the_field(patch, message):
    with pytest.raises(ConfigError, match=message):
        RunConfig.from_dict(patch)
