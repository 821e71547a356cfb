"""The experiment end to end: the smoke experiment's trials as Ray work, a SIGKILL after
its first finished trial, `--resume` that does not rerun it, and results.json with every
method × seed × pool. Plus the config's checks and the aggregation, without Ray."""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from hola_ray.config.reader import ConfigError
from hola_ray.config.scenario import PursuitConfig
from hola_ray.experiment import Experiment, aggregate, deep_merge, trial_state
from hola_ray.methods.config import METHODS
from hola_ray.population.rundir import metrics_differences

ROOT = Path(__file__).resolve().parent.parent
SMOKE = ROOT / "configs" / "experiments" / "smoke.yaml"


def digest(folder: Path) -> str:
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(str(p.relative_to(folder)).encode() + p.read_bytes())
    return h.hexdigest()


def killed_experiment(commands, folder: Path) -> dict:
    """The commands of the test below: the smoke
    experiment one trial at a time, killed by SIGKILL once its first trial is done, then
    resumed."""
    config = yaml.safe_load(SMOKE.read_text())
    config["base"] = str(ROOT / "configs" / "smoke.yaml")
    config["parallel"] = 1  # one trial at a time, so that one is done while the other runs
    # one evaluation seed and a few episodes are enough to check the files
    config["evaluation"] |= {"seeds": [0], "episodes": 2, "cell_episodes": 1}
    path = folder / "smoke.yaml"
    path.write_text(yaml.safe_dump(config))
    out = folder / "exp"
    seen: dict = {"out": out}
    cmd = [sys.executable, "-m", "hola_ray.experiment", "--config", str(path), "--out", str(out)]
    driver = commands.popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    first = out / "trials" / "hola-s0"
    # the runner says "hola-s0: done in …" once the trial's task returned: wait for that line
    seen["first done said"] = any(line.startswith("hola-s0: done in") for line in driver.stdout)
    seen["states"] = (trial_state(first, 1)[0], trial_state(out / "trials" / "sp-s0", 1)[0])
    os.killpg(driver.pid, signal.SIGKILL)  # the driver and the local Ray it started
    driver.wait()
    seen["kept"] = digest(first)
    cmd = [sys.executable, "-m", "hola_ray.experiment", "--resume", str(out)]
    done = commands.popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    stdout, stderr = done.communicate(timeout=600)
    seen["resumed"] = subprocess.CompletedProcess(cmd, done.returncode, stdout, stderr)
    return seen


@pytest.mark.e2e
@pytest.mark.timeout(600)
def test_smoke_experiment_killed_after_one_trial_resumes_without_rerunning_it(
    commands, tmp_path, request
):
    """The smoke experiment killed by SIGKILL once its first trial is done: --resume does
    not rerun that trial, which matches `python -m hola_ray.run` of its config, and
    results.json holds every method × seed × pool. (Its commands: `killed_experiment`.)"""
    seen = killed_experiment(commands, tmp_path)
    # asked for once its commands ran: the other worker makes it meanwhile (both start first)
    smoke_run = request.getfixturevalue("smoke_run")
    out = seen["out"]
    # a base inside the repository is saved relative to it: no path of this machine
    assert yaml.safe_load((out / "experiment.yaml").read_text())["base"] == "configs/smoke.yaml"
    first = out / "trials" / "hola-s0"
    assert seen["first done said"], "the experiment ended before its first trial was done"
    assert seen["states"][0] == "done" and seen["states"][1] != "done", seen["states"]
    kept = seen["kept"]

    done = seen["resumed"]
    assert done.returncode == 0, done.stderr[-3000:]
    assert "hola-s0: done (generation 1), not rerun" in done.stdout
    assert digest(first) == kept  # the finished trial was not touched
    # reproducible: the trial (a Ray task) and `python -m hola_ray.run` of the same config
    # and seed give the same metrics.csv, wall times aside
    assert smoke_run[1].returncode == 0, smoke_run[1].stderr[-3000:]
    assert metrics_differences(smoke_run[0], first) == {}
    assert trial_state(out / "trials" / "sp-s0", 1)[0] == "done"

    results = json.loads((out / "results.json").read_text())
    assert set(results["trials"]) == {"hola-s0", "sp-s0"}
    for trial in results["trials"].values():
        assert 0 < trial["learner_train_s"] <= trial["train_s"]
        assert set(trial["pools"]) == {"hot", "het"}
        for figures in trial["pools"].values():
            for key in ("success", "collision", "length", "score"):
                assert np.isfinite(figures[key])
            assert 0 <= figures["success"] <= 1 and 0 <= figures["score"] <= 1
    hola, sp = results["trials"]["hola-s0"], results["trials"]["sp-s0"]
    assert hola["learner_train_s"] < hola["train_s"]  # its generation 0 is not the learner's
    assert sp["learner_train_s"] == sp["train_s"]  # self-play has no generation 0
    assert set(results["methods"]) == {"hola", "sp"}
    assert (out / "figure.png").stat().st_size > 0
    assert "| hola | het |" in (out / "results.md").read_text()
    progress = json.loads((out / "progress.json").read_text())
    assert {row["status"] for row in progress.values()} == {"done"}
    cached = [
        json.loads((out / "evaluation" / f"{t}.json").read_text()) for t in ("hola-s0", "sp-s0")
    ]
    assert all(set(c["pools"]) == {"hot", "het"} for c in cached)  # a resume reuses them

    # on a new machine: the published experiment restored into a fresh directory, where a
    # resume retrains and replays nothing and writes the same results
    from hola_ray.experiment import publish
    from hola_ray.experiment.runner import Runner

    docs, again = tmp_path / "docs", tmp_path / "again"
    publish.publish(out, docs)
    assert sorted(publish.restore(docs, again)) == ["hola-s0", "sp-s0"]
    assert not (again / "trials" / "hola-s0" / "generations").exists()  # figures, not runs
    runner = Runner(Experiment.from_yaml(again / "experiment.yaml"), again, say=lambda *_: None)
    assert {t: s for t, (s, _) in runner.states().items()} == {"hola-s0": "done", "sp-s0": "done"}
    played = sorted(p.name for p in (again / "evaluation").glob("*.json"))
    assert played == ["hola-s0.json", "sp-s0.json"]  # published as played, and restored
    runner.train()  # nothing to train
    again_results = runner.write_results(runner.evaluate())  # nothing to play
    import ray

    assert not ray.is_initialized()  # no trial trained, no learner played: no Ray started
    for part in ("trials", "methods", "differences"):  # as JSON: NaN (no success) equals NaN
        assert json.dumps(again_results[part], sort_keys=True) == json.dumps(
            results[part], sort_keys=True
        ), part
    assert publish.restore(docs, again) == []  # restored once


def test_each_trial_is_the_base_with_the_experiment_and_method_overrides(tmp_path):
    path = tmp_path / "x.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "base": str(ROOT / "configs" / "smoke.yaml"),
                "overrides": {"env": {"n_evaders": 1}},
                "methods": {"hola": {}, "sp": {"generations": 3, "oracle": {"lr": 1e-3}}},
                "seeds": [4, 5],
            }
        )
    )
    exp = Experiment.from_yaml(path)
    assert exp.trials() == ["hola-s4", "sp-s4", "hola-s5", "sp-s5"]  # seed by seed
    sp = exp.run_config("sp-s5")
    assert (sp.method, sp.seed, sp.generations, sp.oracle.lr) == ("sp", 5, 3, 1e-3)
    assert sp.oracle.train_batch == 1000 and sp.env.n_evaders == 1 and sp.env.horizon == 200
    hola = exp.run_config("hola-s4")
    assert (hola.method, hola.seed, hola.generations, hola.oracle.lr) == ("hola", 4, 1, 3e-4)
    assert deep_merge({"a": {"b": 1, "c": 2}}, {"a": {"b": 3}}) == {"a": {"b": 3, "c": 2}}


def test_a_pilot_is_trained_only(tmp_path):
    """`evaluation: none`: trials and nothing else (a pilot sizes a design on the validation
    teammates and never plays a pool); the differences reported are still hola's."""
    path = tmp_path / "pilot.yaml"
    raw = {"base": str(ROOT / "configs" / "smoke.yaml"), "methods": ["hola", "uniform"]}
    path.write_text(yaml.safe_dump(raw | {"seeds": [0, 1], "evaluation": "none"}))
    exp = Experiment.from_yaml(path)
    assert exp.evaluation is None and exp.pairs() == [("hola", "uniform")]
    assert exp.trials() == ["hola-s0", "uniform-s0", "hola-s1", "uniform-s1"]
    pilot = Experiment.from_yaml(ROOT / "configs" / "experiments" / "pilot-3v2.yaml")
    assert pilot.evaluation is None and len(pilot.seeds) == 4
    config = pilot.run_config("uniform-s3")
    assert (config.env.n_evaders, config.pretrain.learner_start) == (2, "random")
    assert config.grapher.edges_per_learner == 3
    # every shipped 3 vs 2 pilot: trained only, 3 or 4 seeds, at 3 vs 2 with sampled hyperedges
    pilots = sorted((ROOT / "configs" / "experiments").glob("pilot-3v2*.yaml"))
    assert len(pilots) >= 5
    for path in pilots:
        pilot = Experiment.from_yaml(path)
        assert pilot.evaluation is None and len(pilot.seeds) in (3, 4), path.name
        for trial in pilot.trials():
            config = pilot.run_config(trial)
            assert config.env.n_evaders == 2 and config.grapher.edges_per_learner == 3, trial


@pytest.mark.parametrize(
    ("patch", "message"),
    [
        ({"methods": {"hola_x": {}}}, "hola_x: unknown method 'hola_x'"),
        ({"seeds": []}, "seeds must be a non-empty list"),
        ({"color": 1}, r"unknown key\(s\) \['color'\]"),
        ({"methods": {"sp": {"oracle": {"env_steps": -1}}}}, "trial sp-s0: oracle.env_steps"),
        ({"evaluation": {"learner": "last"}}, "evaluation.learner must be final or best"),
        ({"seeds": [True]}, r"seeds\[0\] must be an integer, got True"),
        ({"seeds": [1, 1]}, "seeds must be a non-empty list of distinct integers"),
        ({"parallel": 1.5}, "parallel must be an integer, got 1.5"),
        ({"evaluation": {"episodes": "50"}}, "evaluation.episodes must be an integer"),
        ({"evaluation": {"pools": "hot"}}, "evaluation.pools must be a list"),
        ({"evaluation": {"seeds": []}}, "evaluation.seeds must be a non-empty list"),
        ({"overrides": [1]}, "overrides must be a mapping"),
        ({"methods": {"sp": 3}}, "methods.sp must be a mapping of overrides"),
        ({"evaluation": {"pairs": [["sp", "fcp"]]}}, "evaluation.pairs must be"),
        ({"evaluation": {"protocol": "closed"}}, "evaluation.protocol must be zero-shot or open"),
        ({"evaluation": {"sizes": [6]}}, r"evaluation.sizes must be any of \[2, 3, 4, 5\]"),
    ],
)
def test_a_bad_experiment_config_is_one_clear_error(tmp_path, patch, message):
    config = yaml.safe_load(SMOKE.read_text()) | {"base": str(ROOT / "configs" / "smoke.yaml")}
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(config | patch))
    with pytest.raises(ConfigError, match=message) as err:
        Experiment.from_yaml(path)
    assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)


def episodes(success: np.ndarray, strata: np.ndarray) -> dict[str, np.ndarray]:
    """Evaluation episodes as a learner's record holds them: a crash where it failed."""
    return {
        "success": success,
        "collision": 1 - success,
        "length": np.where(success > 0, 300.0, 1000.0),
        "reward": 20.0 * success,
        "learner_crash": 1 - success,
        "teammate_crash": np.zeros(success.size),
        "stratum": strata,
    }


def test_methods_and_their_paired_differences_from_every_trials_episodes():
    """A method's figure is the mean over its seeds; its interval spans the seeds and the
    episodes; the difference of two methods on the same episodes says who is ahead, and a
    difference whose interval holds zero is reported as a tie."""
    from hola_ray.experiment import results_table

    n = 120
    strata = np.arange(n) % 4  # four partner combinations, 30 episodes each
    rank = np.random.default_rng(0).permutation(n)  # how hard each episode is: shared

    def trial(rate):
        per_episode = episodes((rank < rate * n).astype(float), strata)
        return {
            "hot": {"per_episode": {k: list(v) for k, v in per_episode.items()}, "score_iqm": rate}
        }

    per_trial = {
        "hola-s0": trial(0.2),
        "hola-s1": trial(0.4),
        "sp-s0": trial(0.9),
        "uniform-s0": trial(0.3),
        "uniform-s1": trial(0.31),
    }
    pairs = [("hola", "sp"), ("hola", "uniform")]
    out, diffs = aggregate(per_trial, ["hola", "sp", "uniform"], pairs)
    hot = out["hola"]["hot"]
    assert hot["success"] == pytest.approx(0.3) and hot["trials"] == 2
    assert hot["steps_success"] == pytest.approx(300.0) and hot["reward"] == pytest.approx(6.0)
    lo, hi = hot["success_ci95"]
    assert 0.1 < lo < 0.3 < hi < 0.5 and hot["success_se"] > 0
    behind = diffs["hola-sp"]["hot"]["success"]
    assert behind["mean"] == pytest.approx(-0.6) and behind["ci95"][1] < 0
    tie = diffs["hola-uniform"]["hot"]["success"]
    assert tie["ci95"][0] < 0 < tie["ci95"][1]
    table = results_table(out, diffs, seeds=2)
    assert "| hola-sp | hot | -60.0%" in table and "hola behind" in table
    assert "| hola-uniform | hot |" in table and " tie |" in table
    # the smallest difference the design detects (80 % power, 5 % two-sided): 2.8 se
    row = next(line for line in table.splitlines() if line.startswith("| hola-uniform | hot"))
    assert row.split(" | ")[3] == f"{2.8 * tie['se']:.1%}"


def test_an_experiment_stopped_short_evaluates_its_whole_seeds_and_says_so(tmp_path):
    """`--stop-short`: nothing more is trained; the seeds whose every method is done are
    evaluated (a seed with one trial unfinished is left out whole, so every method is
    figured over the same seeds), and results.json and results.md say the plan was cut."""
    from hola_ray.evaluation.compare import METRICS
    from hola_ray.experiment.command import main
    from hola_ray.experiment.runner import Runner

    path = tmp_path / "x.yaml"
    raw = {"base": str(ROOT / "configs" / "smoke.yaml"), "methods": ["hola", "sp"]}
    path.write_text(yaml.safe_dump(raw | {"seeds": [3, 4, 5]}))
    exp = Experiment.from_yaml(path)
    runner = Runner(exp, tmp_path / "exp", say=lambda *_: None)
    done = {"hola-s3", "sp-s3", "hola-s4", "sp-s5"}  # sp-s4 and hola-s5 not finished
    runner.states = lambda: {t: ("done", 1) if t in done else ("partial", 0) for t in exp.trials()}
    assert runner.whole_seeds() == ([3], ["hola-s4", "sp-s4", "hola-s5", "sp-s5"])

    asked = []
    rng = np.random.default_rng(0)

    def record(rate):
        per_episode = episodes((rng.random(40) < rate).astype(float), np.arange(40) % 4)
        figures = {k: float(np.mean(per_episode.get(k, per_episode["success"]))) for k in METRICS}
        return {
            "hot": figures
            | {f"{k}_se": 0.05 for k in METRICS}
            | {"per_episode": {k: list(v) for k, v in per_episode.items()}, "score_iqm": rate}
        }

    def evaluate(trials=None):
        asked.append(list(trials))
        return {t: record(0.6 if t.startswith("hola") else 0.4) for t in trials}

    runner.evaluate = evaluate
    results = runner.stop_short()
    assert asked == [["hola-s3", "sp-s3"]]  # nothing else played, nothing trained
    assert set(results["trials"]) == {"hola-s3", "sp-s3"}
    assert results["stopped_short"] == {
        "seeds": [3],
        "left_out": ["hola-s4", "sp-s4", "hola-s5", "sp-s5"],
    }
    saved = json.loads((tmp_path / "exp" / "results.json").read_text())
    assert saved["stopped_short"]["seeds"] == [3]
    md = (tmp_path / "exp" / "results.md").read_text()
    assert md.startswith("**Stopped short of the plan**: 1 of 3 seeds evaluated")
    assert "Mean over 1 training seed(s)" in md

    # no whole seed: one clear error; and the flag only ends an experiment under way
    runner.states = lambda: dict.fromkeys(exp.trials(), ("partial", 0))
    with pytest.raises(RuntimeError, match="no seed has every method's trial done"):
        runner.stop_short()
    assert main(["--config", str(path), "--stop-short"]) == 2


@pytest.mark.parametrize(
    ("name", "evaders"),
    [("smoke", 2), ("laptop-3v2", 2), ("paper", 2), ("laptop", 1), ("comparison-3v2", 2)],
)
def test_the_shipped_experiments_load(name, evaders):
    """Every method, three seeds (the 3 vs 2 comparison fifteen: twelve and the extension's
    three, five per build); the laptop comparison at
    competence at 3 vs 1 on the shipped populations, every learner starting from a member;
    the 3 vs 2 comparison from the random weights of its seed, PBT's agents too, seed s
    beside population build s mod 3."""
    exp = Experiment.from_yaml(ROOT / "configs" / "experiments" / f"{name}.yaml")
    assert all(exp.run_config(t).env.n_evaders == evaders for t in exp.trials())
    if name != "smoke":
        seeds = set(range(15)) if name == "comparison-3v2" else {0, 1, 2}
        assert set(exp.methods) == set(METHODS) and set(exp.seeds) == seeds
    if name == "comparison-3v2":
        for trial in exp.trials():
            config = exp.run_config(trial)
            assert config.pretrain.learner_start == "random"
            assert config.pretrain.population in ("none", "{kind}-3v2-s{seed%3}")
            assert (config.population.top_m, config.population.max_size) == (4, 10)
        assert exp.run_config("pbt-s0").pbt.start == "random"
    if name == "laptop":
        for trial in exp.trials():
            config = exp.run_config(trial)
            assert config.pretrain.shipped and config.pretrain.learner_start == "member"


def test_a_variant_is_a_named_method_with_its_own_overrides(tmp_path):
    """Ablation rows: `hola_long: {method: hola, …}` trains method hola with its overrides,
    under its own name; an unknown method or a name that would break trial names is an
    error before anything runs."""
    from hola_ray.config.reader import ConfigError

    config = {
        "base": str(ROOT / "configs" / "smoke.yaml"),
        "methods": {"hola": {}, "hola_long": {"method": "hola", "pretrain": {"env_steps": 4000}}},
        "seeds": [1],
        "evaluation": {"pairs": [["hola_long", "hola"]]},
    }
    path = tmp_path / "x.yaml"
    path.write_text(yaml.safe_dump(config))
    exp = Experiment.from_yaml(path)
    assert exp.trials() == ["hola-s1", "hola_long-s1"]
    long = exp.run_config("hola_long-s1")
    assert (long.method, long.pretrain.env_steps, long.seed) == ("hola", 4000, 1)
    assert exp.run_config("hola-s1").pretrain.env_steps == 2000
    assert exp.pairs() == [("hola", "hola_long"), ("hola_long", "hola")]
    for methods, message in (
        ({"hola_x": {"method": "holla"}}, "unknown method 'holla'"),
        ({"nope": {}}, "unknown method 'nope'"),
        ({"hola-sx": {"method": "hola"}}, "letters, digits and _ only"),
    ):
        path.write_text(yaml.safe_dump(config | {"methods": methods, "evaluation": {}}))
        with pytest.raises(ConfigError, match=message):
            Experiment.from_yaml(path)


def test_a_pool_named_by_its_folder_is_the_same_pool():
    """An experiment's `evaluation.pools` may name a pool folder: it loads under its
    folder's name (as `evaluate` labels it) and gives the named pool's reference returns."""
    from hola_ray.experiment.tasks import _reference

    settings = {"cell_episodes": 1, "episodes": 2, "seeds": [0]}
    by_folder = _reference(str(ROOT / "pools" / "hot"), settings, PursuitConfig())
    by_name = _reference("hot", settings, PursuitConfig())
    np.testing.assert_array_equal(by_folder["returns"], by_name["returns"])
    for seat, played in by_name["seats"].items():  # the learner's scale's reference seats
        np.testing.assert_array_equal(by_folder["seats"][seat]["success"], played["success"])


def test_an_open_team_evaluation_figures_each_method_over_its_seeds(tmp_path):
    """`evaluation.protocol: open-teams`: every trial through the grid, each method over its
    seeds (variants of one method apart), in the trials' scenario, written to
    OUT/open-teams; trials chasing different numbers of evaders, or differing beyond the
    team and the arena, are refused."""
    from types import SimpleNamespace

    import torch

    from hola_ray.experiment.config import EvaluationSettings
    from hola_ray.experiment.runner import Runner
    from hola_ray.policies.learned import random_export

    shipped = Experiment.from_yaml(ROOT / "configs" / "experiments" / "open-teams.yaml")
    assert shipped.evaluation.protocol == "open-teams"
    sizes = {t: shipped.run_config(t).edge_sizes for t in shipped.trials()}
    assert sizes == {"hola_open-s900": (2, 3, 4, 5), "hola-s900": (3,)}
    envs = {
        "hola_open": PursuitConfig(
            n_pursuers=5, n_evaders=2, obs_pursuers=5, horizon=150, arenas=("open", "bar")
        ),
        "hola": PursuitConfig(n_evaders=2, horizon=150),
    }
    trials = [f"{m}-s{k}" for k in (0, 1) for m in envs]
    for t in trials:
        env = envs[t.rpartition("-s")[0]]
        export = random_export(env.obs_dim, seed=len(t) + int(t[-1]), bias_scale=0.5)
        torch.save(export | {"scenario": env.to_dict()}, tmp_path / f"{t}.pt")
    settings = EvaluationSettings(
        episodes=4,
        seeds=(0,),
        pools=("het",),
        protocol="open-teams",
        arenas=("bar",),
        modes=("open",),
        sizes=(4,),
    )
    runner = SimpleNamespace(
        exp=SimpleNamespace(trials=lambda: trials, methods=dict(envs), evaluation=settings),
        configs={t: SimpleNamespace(env=envs[t.rpartition("-s")[0]]) for t in trials},
        learner_file=lambda t: tmp_path / f"{t}.pt",
        out=tmp_path / "exp",
        eval_dir=tmp_path / "exp" / "evaluation",
        say=lambda line: None,
    )
    results = Runner.evaluate_open_teams(runner)
    assert results["protocol"]["methods"] == {
        "hola_open": ["hola_open-s0", "hola_open-s1"],
        "hola": ["hola-s0", "hola-s1"],
    }
    assert results["protocol"]["training_seeds"] == {"hola_open": [0, 1], "hola": [0, 1]}
    (cell,) = results["cells"]
    assert set(cell["differences"]) == {"hola_open − hola"} and len(cell["trials"]) == 4
    assert (tmp_path / "exp" / "open-teams-bar.png").is_file()
    assert json.loads((tmp_path / "exp" / "results.json").read_text())["cells"][0]["pool"] == "het"
    assert results["protocol"]["evaders"] == 2 and len(cell["learners"]) == 2
    # each cell kept as it is played, so a resumed experiment plays only the cells left
    kept = tmp_path / "exp" / "evaluation" / "open-teams"
    assert sorted(p.name for p in kept.iterdir()) == ["bar-open-4-het.json", "bar-open-4-het.npz"]
    said = []
    runner.say = said.append
    assert json.dumps(Runner.evaluate_open_teams(runner)) == json.dumps(results)
    assert said[0].endswith("(kept from an earlier run)"), said
    runner.configs["hola-s1"] = SimpleNamespace(env=PursuitConfig(n_evaders=1))
    with pytest.raises(RuntimeError, match="different numbers of evaders"):
        Runner.evaluate_open_teams(runner)
    runner.configs["hola-s1"] = SimpleNamespace(env=PursuitConfig(n_evaders=2, horizon=300))
    with pytest.raises(RuntimeError, match="differ beyond the team and the arena"):
        Runner.evaluate_open_teams(runner)


def test_the_evaluation_plays_the_trials_scenario_with_one_reward():
    """Trials are evaluated in the scenario they trained in (every env field, not only the
    number of evaders), with the default reward whatever each trained with; trials of
    different scenarios are refused."""
    from types import SimpleNamespace

    from hola_ray.config.scenario import RewardConfig
    from hola_ray.experiment.runner import Runner

    game = PursuitConfig(n_evaders=1, horizon=300, observe_headings=True)
    own_move = dataclasses.replace(game, reward=RewardConfig(approach="own_move"))
    trials = {"hola-s0": game, "sp-s0": own_move}
    runner = SimpleNamespace(
        exp=SimpleNamespace(trials=lambda: list(trials)),
        configs={t: SimpleNamespace(env=env) for t, env in trials.items()},
    )
    assert Runner.evaluation_scenario(runner) == dataclasses.replace(game, reward=RewardConfig())
    runner.configs["sp-s0"] = SimpleNamespace(env=dataclasses.replace(game, horizon=400))
    with pytest.raises(RuntimeError, match="different scenarios"):
        Runner.evaluation_scenario(runner)


def test_a_watching_publisher_started_before_its_experiment_waits_for_it(tmp_path, capsys):
    """`publish RUN DOCS --watch S` started beside a new experiment, before RUN exists,
    waits for its experiment.yaml and then publishes; without --watch it is an error."""
    import threading

    from hola_ray.experiment import publish

    run, docs = tmp_path / "run", tmp_path / "docs"
    with pytest.raises(SystemExit):
        publish.main([str(run), str(docs)])
    assert "holds no experiment.yaml" in capsys.readouterr().err
    returned: list[int] = []
    watcher = threading.Thread(
        target=lambda: returned.append(publish.main([str(run), str(docs), "--watch", "0.01"]))
    )
    watcher.start()
    time.sleep(0.2)
    assert watcher.is_alive() and not docs.exists()  # waiting, nothing published
    (run / "trials" / "sp-s0").mkdir(parents=True)
    for name in ("config.yaml", "metrics.csv", "best.json", "best.pt", "learner.json"):
        (run / "trials" / "sp-s0" / name).write_text(name)
    (run / "progress.json").write_text(json.dumps({"sp-s0": {"status": "done"}}))
    (run / "results.json").write_text("{}")
    (run / "experiment.yaml").write_text("seeds: [0]\n")
    watcher.join(timeout=30)
    assert returned == [0]
    assert (docs / "trials" / "sp-s0" / "best.pt").read_text() == "best.pt"
    assert "waiting for" in capsys.readouterr().out


def test_finished_trials_are_published_and_committed_one_by_one(tmp_path):
    """`python -m hola_ray.experiment.publish RUN DOCS --commit`: each done trial's config,
    metrics, best.pt and best.json copied and committed once; running trials wait; the
    results follow once written."""
    import subprocess

    from hola_ray.experiment import publish

    run, repo = tmp_path / "run", tmp_path / "repo"
    subprocess.run(["git", "init", "-q", str(repo)], check=True)
    for key, value in (("user.email", "t@t"), ("user.name", "t")):
        subprocess.run(["git", "-C", str(repo), "config", key, value], check=True)
    docs = repo / "docs" / "exp"
    (run / "trials").mkdir(parents=True)
    (run / "experiment.yaml").write_text("seeds: [0]\n")
    for t in ("hola-s0", "sp-s0"):
        (run / "trials" / t).mkdir()
        for name in ("config.yaml", "metrics.csv", "best.json", "best.pt", "learner.json"):
            (run / "trials" / t / name).write_text(f"{t} {name}")
        (run / "trials" / t / "members").mkdir()  # never copied
    progress = {"hola-s0": {"status": "done"}, "sp-s0": {"status": "running"}}
    (run / "progress.json").write_text(json.dumps(progress))

    def log() -> list[str]:
        out = subprocess.run(["git", "-C", str(repo), "log", "--format=%s"], capture_output=True)
        return out.stdout.decode().splitlines()

    assert publish.main([str(run), str(docs), "--commit"]) == 0
    assert (docs / "trials" / "hola-s0" / "best.pt").read_text() == "hola-s0 best.pt"
    assert (
        not (docs / "trials" / "sp-s0").exists() and not (docs / "trials/hola-s0/members").exists()
    )
    assert log() == ["exp: hola-s0 published (hola_ray.experiment.publish)"]
    assert publish.main([str(run), str(docs), "--commit"]) == 0  # nothing new: no commit
    assert len(log()) == 1
    progress["sp-s0"]["status"] = "done"
    (run / "progress.json").write_text(json.dumps(progress))
    (run / "results.json").write_text("{}")
    (run / "open-teams-bar.png").write_bytes(b"png")  # an open-team grid's figure
    assert publish.main([str(run), str(docs), "--commit", "--watch", "0.01"]) == 0
    assert log()[0] == "exp: sp-s0, results published (hola_ray.experiment.publish)"
    assert (docs / "results.json").read_text() == "{}"
    assert (docs / "open-teams-bar.png").read_bytes() == b"png"


def test_the_open_team_grids_cells_are_published_as_played_and_restored(tmp_path):
    """A cell of the open-team grid is published once its row is written (its episodes
    with it; one being written waits), again when played anew, and a restore on a new
    machine puts the cells back where the grid looks for them."""
    from hola_ray.experiment import publish

    run, docs, again = tmp_path / "run", tmp_path / "docs", tmp_path / "again"
    (run / "trials").mkdir(parents=True)
    (run / "experiment.yaml").write_text("seeds: [0]\n")
    kept = run / "evaluation" / "open-teams"
    kept.mkdir(parents=True)
    (kept / "zero-shot-open-2-HeT.npz").write_bytes(b"episodes")
    (kept / "zero-shot-open-2-HeT.json").write_text('{"row": 1}')
    (kept / "zero-shot-open-3-HeT.npz").write_bytes(b"being written")  # no row yet
    assert publish.publish(run, docs) == ["1 open-team cell(s)"]
    cells = docs / "evaluation" / "open-teams"
    assert sorted(f.name for f in cells.iterdir()) == [
        "zero-shot-open-2-HeT.json",
        "zero-shot-open-2-HeT.npz",
    ]
    assert publish.publish(run, docs) == []  # nothing new
    (kept / "zero-shot-open-2-HeT.json").write_text('{"row": 2}')  # played again
    (kept / "zero-shot-open-2-HeT.npz").write_bytes(b"again")
    assert publish.publish(run, docs) == ["1 open-team cell(s)"]
    assert (cells / "zero-shot-open-2-HeT.npz").read_bytes() == b"again"
    publish.restore(docs, again)
    back = again / "evaluation" / "open-teams"
    assert (back / "zero-shot-open-2-HeT.json").read_text() == '{"row": 2}'
    assert (back / "zero-shot-open-2-HeT.npz").read_bytes() == b"again"
    assert not (back / "zero-shot-open-3-HeT.npz").exists()


def test_the_status_of_an_experiment_is_every_trial_by_seed_and_method(tmp_path, capsys):
    """`python -m hola_ray status DIR` on an experiment's directory: each trial's state from
    its folder (a restored one is done) or the driver's progress.json (running, failed), the
    generations left, and the time a generation took on disk (generation 0 aside)."""
    from hola_ray.commands.status import main
    from hola_ray.experiment.progress import standing
    from hola_ray.experiment.tasks import RESTORED

    out = tmp_path / "exp"
    raw = {"base": str(ROOT / "configs" / "smoke.yaml"), "methods": ["hola", "sp"]}
    (out / "trials" / "hola-s0").mkdir(parents=True)
    (out / "experiment.yaml").write_text(yaml.safe_dump(raw | {"seeds": [0, 1]}))
    done = out / "trials" / "hola-s0"
    (done / RESTORED).write_text(json.dumps({"generation": 1}))
    (done / "metrics.csv").write_text("generation,wall_s\n0,100.0\n1,10.0\n")
    said = {"sp-s0": {"status": "running"}, "hola-s1": {"status": "failed"}}
    (out / "progress.json").write_text(json.dumps(said))

    view = standing(out)
    assert {t: r["state"] for t, r in view["trials"].items()} == {
        "hola-s0": "done",
        "sp-s0": "running",
        "hola-s1": "failed",
        "sp-s1": "new",
    }
    assert view["generations_left"] == 3 and view["s_per_generation"] == 10.0
    assert main([str(out)]) == 0
    said = capsys.readouterr().out.splitlines()
    assert said[0].endswith("= 4 trials; 1 done, 1 running, 1 failed, 1 not started")
    assert said[1].split() == ["seed", "hola", "sp"]
    assert said[2].split() == ["0", "done", "0/1"] and said[3].split() == [
        "1",
        "0/1",
        "FAILED",
        "-",
    ]
    assert "3 generations left: about 0.0 h" in said[4] and "at the 10 s a generation" in said[4]


def test_the_progress_line_says_the_time_left_at_this_runs_pace():
    from hola_ray.experiment.runner import time_left

    assert time_left(0.0, 0, 80) is None  # nothing trained yet in this run: no pace
    assert time_left(900.0, 12, 0) is None  # nothing left
    # 12 generations in 15 min: 75 s each, 560 more take 11.7 h
    said = time_left(900.0, 12, 560)
    assert said == "about 11.7 h of training left (this run: 12 generations in 15 min)"
    assert (
        time_left(120.0, 1, 9) == "about 18 min of training left (this run: 1 generation in 2 min)"
    )


def test_the_verdict_is_one_sentence_by_the_rule_fixed_before_the_runs():
    """hola − X with HeT: ahead or behind where the interval excludes 0, else a tie; the
    design's goal (every interval not above zero at most 12 points wide) said either way."""
    from hola_ray.experiment.results import DETECTABLE, verdict_sentence

    def diff(mean, lo, hi, se=0.02):
        return {"het": {"success": {"mean": mean, "ci95": [lo, hi], "se": se}}}

    differences = {
        "hola-sp": diff(0.11, 0.03, 0.19),
        "hola-fcp": diff(-0.09, -0.15, -0.02),
        "hola-mep": diff(0.01, -0.04, 0.06, se=0.025),
        "fcp-sp": diff(0.5, 0.4, 0.6),  # not hola's: not in the verdict
    }
    v = verdict_sentence(differences, "hola")
    assert (v["ahead"], v["behind"], v["tie"]) == (["sp"], ["fcp"], ["mep"])
    said = v["sentence"]
    assert said.startswith("With HeT teammates, hola's success is ahead of sp (+11.0 [+3.0, +19")
    assert "behind fcp (-9.0 [-15.0, -2.0])" in said and "tied with mep (+1.0" in said
    assert "fcp-sp" not in said and "the design detects 5.6–7.0 points" in said
    assert v["detectable"] == pytest.approx([DETECTABLE * 0.02, DETECTABLE * 0.025])
    # fcp's interval (13 points) is the widest of those not above zero: over the 12 aimed at
    assert v["widest_not_ahead"] == pytest.approx(0.13) and not v["design_met"]
    assert "wider than the 12 the design aimed at" in said
    narrow = verdict_sentence({"hola-sp": diff(0.02, -0.04, 0.08)}, "hola")  # 12.0 points
    assert narrow["design_met"] and narrow["tie"] == ["sp"] and "ahead" not in narrow["sentence"]
    assert (
        "detects 5.6 points" in narrow["sentence"] and "at most 12.0 points" in narrow["sentence"]
    )
    assert verdict_sentence(differences, "hola", pool="hot") == {}  # no such pool: nothing


def test_the_builds_check_takes_each_build_as_one_observation():
    from hola_ray.experiment.results import build_label, builds_check, builds_table

    assert build_label("{kind}-3v2-s{seed%3}", 4) == "{kind}-3v2-s1"
    assert build_label("mep-3v1-s{seed}", 2) == "mep-3v1-s2"
    assert build_label("none", 4) is None
    # twelve seeds on three builds (seed % 3); hola beside a build, sp beside none, fcp beside
    # its own kind of the same build index; within a build the seeds differ by ±1 point
    jitter = [0.01, -0.01, 0.005, -0.005]
    by_build = {0: 0.20, 1: 0.0, 2: -0.10}  # a build that decides the difference
    success, builds = {}, {}
    for s in range(12):
        diff = by_build[s % 3] + jitter[s // 3]
        success[f"hola-s{s}"] = {"het": 0.5 + diff}
        success[f"sp-s{s}"] = {"het": 0.5}
        success[f"fcp-s{s}"] = {"het": 0.5 - diff}  # hola − fcp: twice hola − sp
        builds[f"hola-s{s}"] = build_label("{kind}-3v2-s{seed%3}", s)
        builds[f"fcp-s{s}"] = build_label("{kind}-3v2-s{seed%3}", s)
        builds[f"sp-s{s}"] = build_label("none", s)
    check = builds_check(success, [("hola", "sp"), ("hola", "fcp")], builds)
    c = check["hola-sp"]["het"]
    assert set(c["builds"]) == {"{kind}-3v2-s0", "{kind}-3v2-s1", "{kind}-3v2-s2"}
    assert c["builds"]["{kind}-3v2-s0"]["seeds"] == 4
    assert c["mean"] == pytest.approx(np.mean(list(by_build.values())), abs=1e-12)
    assert c["p"] < 1e-6  # the builds differ far beyond the seeds' ±1 point
    # over three builds the interval is wide (t on 2 degrees of freedom), where the seeds'
    # own spread (12 seeds taken as independent) would give a narrow one
    lo, hi = c["ci95"]
    seed_diffs = [success[f"hola-s{s}"]["het"] - 0.5 for s in range(12)]
    seed_half = 2.2 * np.std(seed_diffs, ddof=1) / np.sqrt(12)
    assert lo < 0 < hi and (hi - lo) / 2 > 3 * seed_half
    assert check["hola-fcp"]["het"]["mean"] == pytest.approx(2 * c["mean"])
    # no build effect: the same jitter, every build alike, so F is small
    for s in range(12):
        success[f"hola-s{s}"] = {"het": 0.5 + 0.05 + jitter[s // 3]}
    calm = builds_check(success, [("hola", "sp")], builds)["hola-sp"]["het"]
    assert calm["p"] > 0.5 and calm["mean"] == pytest.approx(0.05)
    assert "| hola-sp | het |" in builds_table({"hola-sp": {"het": calm}})
    # one build for every seed, or no build at all: nothing to check
    single = {t: "mep-3v1-s0" for t in builds}
    assert builds_check(success, [("hola", "sp")], single) == {}
    assert builds_check(success, [("hola", "sp")], dict.fromkeys(builds)) == {}
    assert builds_table({}) == ""
    # every seed of a build alike: F is finite (results.json is JSON), p near 0 or 1
    flat = {
        t: {"het": 0.5 + (0.1 if t.startswith("hola") and int(t[6:]) % 3 == 0 else 0.0)}
        for t in success
    }
    assert builds_check(flat, [("hola", "sp")], builds)["hola-sp"]["het"]["p"] < 1e-12
    same = {t: {"het": 0.5} for t in success}
    assert builds_check(same, [("hola", "sp")], builds)["hola-sp"]["het"]["p"] == 1.0
    json.dumps(builds_check(flat, [("hola", "sp")], builds), allow_nan=False)
