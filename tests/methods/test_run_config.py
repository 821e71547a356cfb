"""Run configs: the shipped YAMLs load, round-trip, and bad values fail naming the field."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from hola_ray.commands.run import DEFAULT
from hola_ray.config.reader import ConfigError
from hola_ray.methods.config import RunConfig

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


def test_a_method_without_a_population_takes_only_its_start_from_the_shipped_one(tmp_path):
    """`python -m hola_ray.run --set method=sp` on the embedded default (which adopts a
    shipped population and starts its learner from a member): self-play has no population,
    so the shipped one gives its learner's start only, and with `population: none` it
    starts from random weights; hola takes the population (built in another scenario: its
    G_0 weighed again) and starts from its member.
    Generation zero is one value, resolved from the config and the folder alone."""
    from hola_ray.commands.run import DEFAULT
    from hola_ray.methods.generation_zero import resolve
    from hola_ray.population.rundir import RunDir

    config = RunConfig.from_dict(DEFAULT | {"method": "sp"})
    assert config.pretrain.shipped and config.strategy.origin.kind is None
    zero = resolve(config, RunDir(tmp_path / "sp"))
    assert (zero.source, zero.learner_start) == ("none", "shipped")
    alone = RunConfig.from_dict(DEFAULT | {"method": "sp", "pretrain": {"population": "none"}})
    zero = resolve(alone, RunDir(tmp_path / "alone"))
    assert (zero.source, zero.learner_start) == ("none", "random")
    zero = resolve(RunConfig.from_dict(DEFAULT), RunDir(tmp_path / "hola"))
    # built in the default's own scenario and reward: G_0 is taken as shipped
    assert (zero.source, zero.learner_start) == ("shipped", "member") and not zero.differ
    assert zero.donor.name == "mep-3v1-s0" and zero.manifest["kind"] == "mep"
    # under another reward than the build's, its G_0 is weighed again
    own = DEFAULT | {"env": {**DEFAULT["env"], "reward": {"approach": "own_move"}}}
    zero = resolve(RunConfig.from_dict(own), RunDir(tmp_path / "own"))
    assert (zero.source, zero.learner_start) == ("reweigh", "member") and zero.differ
    assert not (tmp_path / "hola").exists() and not (tmp_path / "own").exists()  # nothing written


def test_a_common_start_is_taken_by_every_method_but_never_from_a_partner(tmp_path):
    """`pretrain.start_agent` names a shipped population whose last node every method's
    learner starts from (self-play included; PBT begins every agent as a copy); one that is a
    member of the run's own generation 0 is refused before anything starts."""
    from hola_ray.methods.generation_zero import resolve
    from hola_ray.population.rundir import RunDir
    from hola_ray.population.shipped import PopulationError

    def config(start: str, population: str = "mep-3v1-s0", **top) -> RunConfig:
        pretrain = DEFAULT["pretrain"] | {"start_agent": start, "population": population}
        return RunConfig.from_dict(DEFAULT | top | {"pretrain": pretrain})

    for method in ("hola", "sp", "uniform"):
        zero = resolve(config("fcp-3v1-s0", method=method), RunDir(tmp_path / method))
        assert zero.learner_start == "agent"
    # PBT builds its agents as copies of the start: never beside a shipped population
    zero = resolve(config("fcp-3v1-s0", "none", method="pbt"), RunDir(tmp_path / "pbt"))
    assert (zero.source, zero.learner_start) == ("build", "random")
    with pytest.raises(PopulationError, match="set pretrain.population: none"):
        resolve(config("fcp-3v1-s0", method="pbt"), RunDir(tmp_path / "pbt-shipped"))
    with pytest.raises(PopulationError, match="no partner of its learner"):
        resolve(config("mep-3v1-s0"), RunDir(tmp_path / "own"))
    with pytest.raises(PopulationError, match="no shipped population 'nowhere-3v1'"):
        resolve(config("nowhere-3v1"), RunDir(tmp_path / "missing"))
    assert not any(tmp_path.iterdir())  # nothing written


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
        ({"pretrain": {"learner_start": "best"}}, r"learner_start must be random or member"),
        ({"pretrain": {"alpha_until": -1}}, r"pretrain.alpha_until must be an integer >= 0"),
        ({"pretrain": {"until_in_a_row": 0}}, r"pretrain.until_in_a_row must be"),
        ({"pretrain": {"start_agent": ""}}, r"pretrain.start_agent must be none or a shipped"),
        ({"pbt": {"start": "copies"}}, r"pbt.start must be self-play or mixed or random"),
        (
            {"method": "pbt", "pbt": {"start": "random"}, "pretrain": {"population": "pbt-3v1-s0"}},
            r"pbt.start must be not random with a population or a start agent",
        ),
        # absurd sizes: typos, not runs
        ({"oracle": {"hidden": [10**9]}}, r"oracle.hidden must be a list of at most 16"),
        ({"oracle": {"envs_per_runner": 10**8}}, r"envs_per_runner must be an integer in \[1,"),
        ({"oracle": {"env_steps": 10**15}}, r"oracle.env_steps must be an integer in \[1,"),
        ({"population": {"max_size": 10**5}}, r"population.max_size must be an integer in"),
        ({"grapher": {"episodes_per_edge": 10**9}}, r"episodes_per_edge must be an integer in"),
        ({"env": {"horizon": 10**9}}, r"env.horizon must be an integer in \[1, 1,000,000\]"),
        ({"generations": 10**9}, r"generations must be an integer in \[0, 1,000,000\]"),
    ],
)
def test_bad_values_name_the_field(patch, message):
    with pytest.raises(ConfigError, match=message):
        RunConfig.from_dict(patch)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("method: hola\noracle:\n  lr: [1, 2\n", r"bad.yaml:4:1: not valid YAML: expected ','"),
        (
            "method: hola\nenv:\n  n_pursuers: 3\n  reward:\n    collision: -10\n",
            r"bad.yaml:5: env.reward.collision must be a finite number >= 0, got -10",
        ),
        ("method: hola\nenv:\n  n_pursuers: 0\n", r"bad.yaml:3: env.n_pursuers must be"),
        (
            "method: hola\ngrapher:\n  episodes: 3\n",
            r"bad.yaml:3: unknown key\(s\) grapher.episodes",
        ),
        ("method: hola\n\n\npopulation:\n  max_size: 2\n", r"bad.yaml:5: population.max_size"),
        ("", r"bad.yaml is empty: a run config needs at least its method"),
    ],
)
def test_a_bad_file_is_one_line_naming_file_line_and_field(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=message) as err:
        RunConfig.from_yaml(path)
    assert len(str(err.value).splitlines()) == 1


def test_numbers_in_scientific_notation_are_numbers(tmp_path):
    path = tmp_path / "sci.yaml"
    path.write_text("method: hola\noracle:\n  env_steps: 1e5\n  lr: 3e-4\n  train_batch: 2.048e3\n")
    c = RunConfig.from_yaml(path)
    assert c.oracle.env_steps == 100_000 and isinstance(c.oracle.env_steps, int)
    assert c.oracle.lr == 3e-4 and c.oracle.train_batch == 2048
    path.write_text("method: hola\noracle:\n  env_steps: 2.5e0\n")  # not a whole number
    with pytest.raises(ConfigError, match="oracle.env_steps must be an integer, got 2.5"):
        RunConfig.from_yaml(path)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("oracle:\n  hidden: 64\n", "oracle.hidden must be a list, got 64"),
        ("oracle:\n  hidden: [64, 6.5]\n", "oracle.hidden[1] must be an integer, got 6.5"),
        ("oracle:\n  lr: .nan\n", "oracle.lr must be a finite number, got nan"),
        ("oracle:\n  lr: '1e-3'\n", "oracle.lr must be a finite number, got '1e-3'"),
        ("generations: true\n", "generations must be an integer, got True"),
        ("oracle: null\n", "oracle must be a mapping, got None"),
        ("env: null\n", "env must be a mapping, got None"),
        ("env:\n  n_pursuers: true\n", "env.n_pursuers must be an integer, got True"),
        ("seed: 1.5\n", "seed must be an integer, got 1.5"),
    ],
)
def test_malformed_values_are_one_line_naming_file_line_and_field(tmp_path, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text("method: hola\n" + text)
    with pytest.raises(ConfigError) as err:
        RunConfig.from_yaml(path)
    line = str(err.value)
    assert "\n" not in line and message in line, line
    assert line.startswith(f"{path}:"), line  # file:line: first


def test_set_overrides_one_value_read_as_yaml(tmp_path):
    """`python -m hola_ray.run --set section.field=value`: values read as YAML (1e-4 a
    number, lists, nested sections), applied over the file or the embedded default."""
    from hola_ray.commands import run

    args = run.parse_args(
        [
            "--config",
            str(Path(__file__).resolve().parents[2] / "configs" / "smoke.yaml"),
            "--out",
            str(tmp_path / "r"),
        ]
        + ["--set", "oracle.lr=1e-4", "--set", "oracle.hidden=[8, 8]"]
        + ["--set", "env.reward.approach=own_move", "--set", "method=sp"]
    )
    config, _ = run.resolve(args)
    assert config.oracle.lr == 1e-4 and config.oracle.hidden == (8, 8)
    assert config.env.reward.approach == "own_move" and config.method == "sp"
    assert config.oracle.env_steps == 2000  # the rest is the file's


@pytest.mark.parametrize(
    ("sets", "message"),
    [
        (["oracle.lr=abc"], r"^--set: oracle.lr must be a finite number, got 'abc'$"),
        (["population.top_m=true"], r"^--set: population.top_m must be an integer"),
        (["oracle.hidden=64"], r"^--set: oracle.hidden must be a list"),
        (["oracle.nope=1"], r"^--set: unknown key\(s\) oracle.nope"),
        (["oops"], r"write section.field=value"),
        (["generations.x=1"], r"generations is not a section"),
    ],
)
def test_a_bad_set_is_one_line_naming_it(tmp_path, sets, message):
    from hola_ray.commands import run

    argv = ["--out", str(tmp_path / "r")] + [a for s in sets for a in ("--set", s)]
    with pytest.raises(ConfigError, match=message):
        run.resolve(run.parse_args(argv))
