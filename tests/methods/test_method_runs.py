"""Each method's run, end to end on the smoke config: self-play, FCP and MEP (best
responses to a fixed population) and PBT (agents in turn, exploit and explore). One Ray
session for the module, each run a `Trainer` in this process (what `python -m hola_ray.run`
calls; the CLI around it is tested in tests/test_run.py)."""

from __future__ import annotations

import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

from hola_ray.commands import status
from hola_ray.config.reader import ConfigError, require
from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.rollout import rollout
from hola_ray.methods.base import Method, Origin
from hola_ray.methods.config import RunConfig
from hola_ray.methods.generation_zero import KEY_FILE
from hola_ray.methods.registry import register, unregister
from hola_ray.methods.trainer import Trainer
from hola_ray.policies.learned import MLPPolicy
from hola_ray.population.rundir import RunDir
from hola_ray.population.state import Decision, Population

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / "configs" / "smoke.yaml"


@pytest.fixture(scope="module", autouse=True)
def _ray(ray_session):
    return ray_session


def train(config: dict, out: Path, capsys, adopt_from: tuple[Path, ...] = ()) -> str:
    """Train `config` into `out`; what the trainer printed."""
    capsys.readouterr()
    Trainer(RunConfig.from_dict(config), out, progress=False, adopt_from=adopt_from).fit()
    return capsys.readouterr().out


@pytest.fixture(scope="module")
def mep_zero(tmp_path_factory) -> Path:
    """hola's generation 0 on the smoke config (MEP's population and G_0), built once: the
    methods that share it (mep, the toy method) adopt it, as an experiment's trials do."""
    out = tmp_path_factory.mktemp("mep_zero") / "hola"
    smoke = yaml.safe_load(SMOKE.read_text())
    Trainer(RunConfig.from_dict(smoke | {"generations": 0}), out, progress=False).fit()
    return out


def test_self_play_run_seats_one_learner_and_keeps_its_best(tmp_path, capsys):
    """method sp: no population and no pre-training; each generation judges the exported
    learner as the whole team; learner.pt is the latest, best.pt the best judged."""
    smoke = yaml.safe_load(SMOKE.read_text())
    run_config = smoke | {"method": "sp", "generations": 2}
    out = tmp_path / "sp"
    train(run_config, out, capsys)
    r = RunDir(out)
    assert r.completed() == [1, 2]
    assert not list(r.members.glob("*.pt"))
    rows = r.metrics_rows()
    assert all(row["population_size"] == 0 and "grapher_s" not in row for row in rows)
    assert all(row["learner_episodes"] == smoke["grapher"]["episodes_per_edge"] for row in rows)
    best = r.best_generation()
    score = {row["generation"]: (row["learner_success"], -row["learner_collision"]) for row in rows}
    assert score[best] == max(score.values())
    env = PursuitConfig.from_yaml(SMOKE)
    for path in (r.learner, r.best):
        assert rollout(env, [MLPPolicy.load(env, path)] * 3, episodes=2).episodes == 2
    assert status.main([str(out), "--plot"]) == 0


def test_random_weights_are_one_start_for_every_method_of_a_seed(tmp_path, capsys):
    """`pretrain.learner_start: random` is a common start (a comparison measures the
    methods, not their starts): at one seed the learner's initial weights are the same
    whichever method seats it (self-play, partners
    drawn by φ, FCP's larger population), and another seed's differ; PBT's agents, with
    `pbt.start: random`, are each a copy of them."""
    import numpy as np

    from hola_ray.oracle import LEARNER

    smoke = yaml.safe_load(SMOKE.read_text())
    fcp = {"method": "fcp", "population": smoke["population"] | {"max_size": 6}}
    starts = {}
    for name, patch in [("hola", {}), ("sp", {"method": "sp"}), ("fcp", fcp), ("s1", {"seed": 1})]:
        c = RunConfig.from_dict(smoke | patch)
        oracle = c.strategy.make_oracle(c)
        try:
            starts[name] = oracle.weights([LEARNER])[LEARNER]
        finally:
            oracle.stop()

    def same(a, b):
        return a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)

    assert same(starts["hola"], starts["sp"]) and same(starts["hola"], starts["fcp"])
    assert not same(starts["hola"], starts["s1"])
    pbt = {"method": "pbt", "generations": 0, "pbt": {"start": "random"}}
    said = train(smoke | pbt, tmp_path / "pbt", capsys)
    assert "3 agents, each a copy of the learner's random weights at seed 0" in said
    run = RunDir(tmp_path / "pbt")
    agents = [run.load_member_state(v) for v in range(smoke["population"]["initial_size"])]
    assert all(same(a, starts["hola"]) for a in agents)


@pytest.mark.parametrize("method", ["fcp", "mep"])
def test_best_response_methods_keep_their_population_fixed(tmp_path, capsys, method, mep_zero):
    """fcp: the population is two self-play agents' start, middle and end checkpoints;
    mep: the MEP population, partners then drawn by the rank of the learner's returns.
    Neither admits the learner; both train it as a best response, drawn as they say."""
    import json

    smoke = yaml.safe_load(SMOKE.read_text())
    patch = {"method": method, "generations": 1}
    if method == "fcp":
        patch |= {"fcp": {"agents": 1, "env_steps": 2000}, "population": {"max_size": 4}}
    run_config = smoke | patch
    out = tmp_path / method
    said = train(run_config, out, capsys, adopt_from=(mep_zero,))  # fcp takes nothing
    r = RunDir(out)
    assert r.completed() == [0, 1]
    assert ("adopted from" in said) == (method == "mep")
    rows = r.metrics_rows()
    size = 3 if method == "fcp" else smoke["population"]["initial_size"]
    assert [row["population_size"] for row in rows] == [size] * 2
    assert rows[1]["accepted"] == 0
    states = [json.loads((r.generation(g) / "state.json").read_text()) for g in (0, 1)]
    assert all(sorted(s["population"]["slots"]) == [str(v) for v in range(size)] for s in states)
    phi = json.loads((r.generation(1) / "phi.json").read_text())
    if method == "fcp":
        assert "trained 1 self-play agent(s) for FCP (3 checkpoints)" in said
        assert all(v == pytest.approx(1 / 3) for v in phi.values())
    else:
        from hola_ray.population.rules import rank_priorities

        returns = {int(k): v for k, v in states[1]["population"]["learner_returns"].items()}
        assert set(returns) == set(range(size))  # every member met the learner
        full = {v: returns.get(v) for v in range(size)}
        assert {int(k): v for k, v in phi.items()} == pytest.approx(rank_priorities(full, 3.0))


def test_pbt_trains_its_agents_in_turn_and_exploits_the_best(tmp_path, capsys):
    """pbt: three agents trained jointly, then one per generation with the other two. Once
    each has trained, the lowest-scoring one takes the best one's weights and its lr and
    entropy coefficient, perturbed. The exploit is forced: after agents 0 and 1 trained,
    their saved scores are raised far above anything a smoke run reaches, so agent 2,
    trained on resuming, is the lowest and must exploit agent 1 (the top)."""
    import json

    import torch

    smoke = yaml.safe_load(SMOKE.read_text())
    patch = {"method": "pbt", "generations": 2, "pbt": {"quantile": 0.34, "perturb": [0.5]}}
    out = tmp_path / "pbt"
    said = train(smoke | patch, out, capsys)
    assert "pre-trained 3 members jointly (PBT's start)" in said
    r = RunDir(out)
    saved = r.generation(2) / "state.json"
    state = json.loads(saved.read_text())
    assert sorted(state["population"]["extra"]["agent_scores"]) == ["0", "1"]  # 2 not yet
    state["population"]["extra"]["agent_scores"] = {"0": 1e6, "1": 2e6}
    saved.write_text(json.dumps(state))

    said = train(smoke | patch | {"generations": 3}, out, capsys)
    states = [json.loads((r.generation(g) / "state.json").read_text()) for g in (1, 2, 3)]
    assert [s["decision"]["slot"] for s in states] == [0, 1, 2]  # each agent in turn
    assert all(s["decision"]["replaced"] == g for g, s in enumerate(states))  # its parent
    last = states[-1]
    slots = {int(k): v for k, v in last["population"]["slots"].items()}
    source = last["decision"]["copied_from"]
    assert source is not None and slots[source] == 1  # exploits the top agent
    assert f"it exploits node {source}" in said
    scores = {int(k): v for k, v in last["population"]["extra"]["agent_scores"].items()}
    assert scores[2] == scores[1] == 2e6  # and takes its score
    hyper = {int(k): v for k, v in last["population"]["extra"]["agent_hyper"].items()}
    for h in ("lr", "entropy_coef"):
        assert hyper[2][h] == pytest.approx(0.5 * hyper[1][h])  # explores: × perturb
    copied = torch.load(r.member_export(last["decision"]["candidate"]), weights_only=False)
    original = torch.load(r.member_export(source), weights_only=False)
    for w1, w2 in zip(copied["weights"], original["weights"], strict=True):
        assert torch.equal(w1, w2)


def test_pre_training_judges_its_members_as_copies_and_stops_once_all_are_competent(
    tmp_path, capsys, monkeypatch
):
    """pretrain.until_success: the members are judged as teams of their own copies every
    check_every env steps. Competent at the second check (the judge's figures replaced):
    pre-training stops there, with half the cap's env steps. Stopped during its second
    check, a build resumes from the members saved at the first; never competent (success
    1.0 asked), it trains to the cap and metrics.csv says so."""
    from hola_ray.methods import pretrain
    from hola_ray.oracle.trainer import Oracle

    smoke = yaml.safe_load(SMOKE.read_text())
    until = {"env_steps": 4000, "check_every": 1000, "until_episodes": 6}
    never = until | {"env_steps": 2000, "until_success": 1.0}

    # pretrain.alpha_until: the bonus for the first 1,000 env steps, then α 0 on the weights
    alphas: list[float] = []
    real_oracle_init = Oracle.__init__

    def seen(self, env, config, seating, seed):
        alphas.append(seating.mep_alpha)
        real_oracle_init(self, env, config, seating, seed)

    monkeypatch.setattr(Oracle, "__init__", seen)
    annealed = never | {"alpha": 0.05, "alpha_until": 1000}
    said = train(smoke | {"generations": 0, "pretrain": annealed}, tmp_path / "anneal", capsys)
    assert alphas == [0.05, 0.0] and "pre-train: α 0 from 1," in said
    monkeypatch.setattr(Oracle, "__init__", real_oracle_init)

    judged = []
    real = pretrain.members_as_copies

    def judge(config, oracle):
        judged.append(real(config, oracle))  # played, then called competent the second time
        ok = {"success": 0.9, "collision": 0.1}
        return [ok] * len(judged[-1]) if len(judged) == 2 else judged[-1]

    monkeypatch.setattr(pretrain, "members_as_copies", judge)
    goal = {"until_success": 0.85, "until_collision": 0.15}
    said = train(smoke | {"generations": 0, "pretrain": until | goal}, tmp_path / "ok", capsys)
    assert len(judged) == 2 and "competent after 2," in said
    (row,) = RunDir(tmp_path / "ok").metrics_rows()
    assert row["pretrain_competent"] == 1 and 2000 <= row["pretrain_env_steps"] < 3000
    assert row["pretrain_members_success_min"] == 0.9

    # `until_in_a_row: 2`: competent at the 2nd check and the 4th, not the 3rd: on to the
    # 5th, where the streak reaches 2
    judged.clear()

    def streaky(config, oracle):
        judged.append(real(config, oracle))
        ok = {"success": 0.9, "collision": 0.1}
        return [ok] * len(judged[-1]) if len(judged) in (2, 4, 5) else judged[-1]

    monkeypatch.setattr(pretrain, "members_as_copies", streaky)
    twice = until | goal | {"env_steps": 6000, "until_in_a_row": 2}
    said = train(smoke | {"generations": 0, "pretrain": twice}, tmp_path / "twice", capsys)
    assert len(judged) == 5 and "(2 checks in a row)" in said
    assert said.count("every member competent, 1 check(s) in a row") == 2
    (row,) = RunDir(tmp_path / "twice").metrics_rows()
    assert 5000 <= row["pretrain_env_steps"] < 6000
    # the saved progress holds every check, the deciding 5th included (the manifest's record)
    _, progress = RunDir(tmp_path / "twice").load_pretrain()
    assert [c["env_steps"] for c in progress["checks"]][-1] == row["pretrain_env_steps"]
    assert len(progress["checks"]) == 5 and progress["checks"][-1]["success"][0] == 0.9

    # a build stopped after its deciding check, before G_0 was weighed (its pre-training
    # saved, nothing else): resumed, it trains no more
    decided = RunDir(tmp_path / "decided")
    shutil.copytree(RunDir(tmp_path / "twice").pretrain, decided.pretrain)
    said = train(smoke | {"generations": 0, "pretrain": twice}, decided.root, capsys)
    assert len(judged) == 5 and "members as copies: success" not in said
    assert "(2 checks in a row)" in said
    (row,) = decided.metrics_rows()
    assert row["pretrain_competent"] == 1 and row["pretrain_members_success_min"] == 0.9
    assert (
        pretrain.passing_in_a_row(
            [{"success": [0.9], "collision": [0.1]}, {"success": [0.5], "collision": [0.1]}]
            + [{"success": [0.9], "collision": [0.1]}] * 2,
            0.85,
            0.15,
        )
        == 2
    )  # the trailing streak only

    # stopped during its second check: the build resumes from the members saved at the first
    judged.clear()

    def stopped(config, oracle):
        judged.append(real(config, oracle))
        if len(judged) == 2:
            raise KeyboardInterrupt
        return judged[-1]

    monkeypatch.setattr(pretrain, "members_as_copies", stopped)
    # with a learning rate decaying over the build: the resumed build's goes on from the check
    lr, schedule = 1e-3, {"lr_decay_env_steps": 2000, "lr_final": 0.0}
    decaying = smoke | {"oracle": smoke["oracle"] | schedule | {"lr": lr}}
    with pytest.raises(KeyboardInterrupt):
        train(decaying | {"generations": 0, "pretrain": never}, tmp_path / "stopped", capsys)
    run = RunDir(tmp_path / "stopped")
    states, progress = run.load_pretrain()
    assert run.completed() == [] and 1000 <= progress["env_steps"] < 2000
    [first] = progress["checks"]  # the check's figures, kept with its members
    assert first["env_steps"] == progress["env_steps"]
    assert first["success"] == [round(f["success"], 4) for f in judged[0]]
    seated: list[dict] = []
    monkeypatch.setattr(pretrain, "members_as_copies", real)
    monkeypatch.setattr(Oracle, "set_trained_weights", lambda self, w: seated.append(dict(w)))
    rates: list[list[float]] = []
    real_start = Oracle.start_schedules_at

    def start_at(self, env_steps):
        real_start(self, env_steps)
        for r in self.algo.learner_group.foreach_learner(
            lambda learner: [learner._get_optimizer_lr(o) for o in learner._optimizer_lr_schedules]
        ):
            rates.append(r.get())

    monkeypatch.setattr(Oracle, "start_schedules_at", start_at)
    said = train(decaying | {"generations": 0, "pretrain": never}, tmp_path / "stopped", capsys)
    assert f"pre-train: resumed after {progress['env_steps']:,} env steps" in said
    # every member's optimizer at lr · (1 − done / 2000), not back at lr
    (members,) = rates
    assert len(members) == smoke["population"]["initial_size"]
    assert members == pytest.approx([lr * (1 - progress["env_steps"] / 2000)] * len(members))
    assert said.count("members as copies: success") == 1  # only the check after the resume
    assert [sorted(w) for w in seated] == [sorted(states)]
    for mid, state in states.items():
        assert all((seated[0][mid][k] == v).all() for k, v in state.items())
    (row,) = run.metrics_rows()
    assert row["pretrain_resumed_at"] == progress["env_steps"]
    # never competent: trained to the cap, and metrics.csv says so
    assert "(self-play; 2,000 env steps, not all competent)" in said
    assert row["pretrain_competent"] == 0 and row["pretrain_env_steps"] >= 2000
    assert 0 <= row["pretrain_members_success_min"] < 1.0


def test_a_run_resumed_after_a_generation_trains_on_as_the_undisturbed_one(
    tmp_path, capsys, mep_zero
):
    """Stopped after generation 1 and resumed, a run trains generation 2 as the undisturbed
    run does, to the bit: each generation folder keeps the learner's Adam state, KL
    coefficient and env steps (learner.training.pt, here with the lr decaying over them)
    beside its weights, and each generation samples and shuffles from generators of (seed,
    generation) (`Oracle.reseed`), whatever was sampled before."""
    import torch

    from hola_ray.population.rundir import metrics_differences

    smoke = yaml.safe_load(SMOKE.read_text())
    smoke["oracle"] |= {"lr_decay_env_steps": 5000, "lr_final": 1e-5}
    whole, part = tmp_path / "whole", tmp_path / "part"
    train(smoke | {"generations": 2}, whole, capsys, adopt_from=(mep_zero,))
    train(smoke | {"generations": 1}, part, capsys, adopt_from=(mep_zero,))
    said = train(smoke | {"generations": 2}, part, capsys)
    assert "resuming after generation 1" in said
    assert RunDir(part).completed() == [0, 1, 2]
    assert metrics_differences(whole, part) == {}
    a, b = RunDir(whole), RunDir(part)
    assert_same(a.load_learner_state(2), b.load_learner_state(2))
    training = b.load_training_state(2)
    assert_same(a.load_training_state(2), training)
    assert training["env_steps"] >= 2 * smoke["oracle"]["env_steps"]
    [adam] = training["optimizers"].values()
    assert adam["state"] and all(torch.is_tensor(v["exp_avg"]) for v in adam["state"].values())


def assert_same(a, b, where: str = "") -> None:
    """Two nested states (dicts, lists, tensors, arrays, numbers) equal to the bit."""
    import numpy as np
    import torch

    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            assert_same(a[k], b[k], f"{where}/{k}")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            assert_same(x, y, f"{where}/{i}")
    elif torch.is_tensor(a) or isinstance(a, np.ndarray):
        assert np.array_equal(np.asarray(a), np.asarray(b)), where
    else:
        assert a == b, where


def test_a_run_adopts_the_generation_zero_of_a_run_with_the_same_pre_training(
    tmp_path, capsys, mep_zero
):
    """hola and uniform of one seed build the same G_0 (MEP's population): uniform taking
    hola's generation 0 holds the same members and hyperedges as uniform building its own,
    and draws them by its own rules (the method's, not the folder's); a run whose
    pre-training differs takes nothing."""

    smoke = yaml.safe_load(SMOKE.read_text()) | {"generations": 0}
    donor, own, adopted = mep_zero, tmp_path / "uniform-own", tmp_path / "uniform"
    train(smoke | {"method": "uniform"}, own, capsys)
    capsys.readouterr()
    Trainer(
        RunConfig.from_dict(smoke | {"method": "uniform"}),
        adopted,
        progress=False,
        adopt_from=(donor,),
    ).fit()
    assert "gen 0: adopted from hola" in capsys.readouterr().out
    a, b = RunDir(adopted), RunDir(own)
    state = a.read_json(0, "state.json")["population"]
    assert state["hyfog"] == b.read_json(0, "state.json")["population"]["hyfog"]
    for v in map(int, state["slots"]):
        assert a.member_export(v).read_bytes() == b.member_export(v).read_bytes()
    assert len(a.metrics_csv.read_text().splitlines()) == 2  # header and generation 0
    # a run takes a donor's generation 0 only when the key the donor wrote is its own: the
    # same seed and pre-training give hola's key to uniform, another pre-training does not
    marker = RunDir(donor).generation(0) / KEY_FILE
    key = RunConfig.from_dict(smoke | {"method": "uniform"}).generation_zero_key()
    assert marker.read_text() == key
    other = smoke | {"method": "uniform", "pretrain": {"env_steps": 3000}}
    assert RunConfig.from_dict(other).generation_zero_key() != key


def test_a_shipped_population_is_built_verified_adopted_and_refused_when_it_does_not_fit(
    tmp_path, capsys, monkeypatch
):
    """`python -m hola_ray populations build` on a tiny population config: the manifest
    names every member's files, hashes, role and team figures; a run with
    `pretrain.population` takes that generation 0 and trains on; a changed file, another
    layout, another kind of population and a member that is a pool's are each refused in
    one line."""
    import json
    import shutil

    from hola_ray.commands import populations
    from hola_ray.evaluation.pools import POOLS_DIR
    from hola_ray.population import shipped

    configs, shelf = tmp_path / "configs", tmp_path / "shelf"
    configs.mkdir()
    monkeypatch.setattr(populations, "CONFIGS", configs)
    monkeypatch.setattr(populations, "RUNS", tmp_path / "runs")
    monkeypatch.setattr(populations, "POPULATIONS_DIR", shelf)
    monkeypatch.setattr(shipped, "POPULATIONS_DIR", shelf)
    smoke = yaml.safe_load(SMOKE.read_text()) | {"generations": 0}
    (configs / "tiny-s0.yaml").write_text(yaml.safe_dump(smoke))
    assert populations.main(["build", "tiny-s0", "--episodes", "4", "--quiet"]) == 0
    said = capsys.readouterr().out
    assert "population tiny-s0 written to" in said and "node_0" in said
    bar = "(as copies: success >= 60%, collision <= 35%)"
    assert f"[tiny-s0] NOT at the contract's 3v2 bar {bar}" in said
    folder = shelf / "tiny-s0"
    manifest = json.loads((folder / "manifest.json").read_text())
    assert manifest["kind"] == "mep" and manifest["seed"] == 0
    assert manifest["layout"] == RunConfig.from_dict(smoke).layout()
    assert len(manifest["members"]) == smoke["population"]["initial_size"]
    for entry in manifest["members"].values():
        assert entry["role"] == "member" and entry["scenario"] == "3v2"
        assert entry["team_episodes"] == 4 and 0 <= entry["team_success"] <= 1
    assert "generations/gen_0000/edges.json" in manifest["generation_files"]

    # adopted, by name with the run's seed, and trained on from its most preferred member
    from hola_ray.oracle import LEARNER, Oracle

    started: list[dict] = []
    original = Oracle.set_trained_weights

    def recorded(self, weights):
        started.append(dict(weights))
        return original(self, weights)

    monkeypatch.setattr(Oracle, "set_trained_weights", recorded)
    run = smoke | {
        "generations": 1,
        "pretrain": {"population": "tiny-s{seed}", "learner_start": "member"},
    }
    said = train(run, tmp_path / "run", capsys)
    assert "gen 0: the shipped population tiny-s0 (3 members" in said
    r = RunDir(tmp_path / "run")
    rows = r.metrics_rows()
    assert r.completed() == [0, 1] and rows[0]["adopted_from"] == "tiny-s0"
    eta = {int(k): v for k, v in r.read_json(0, "eta.json").items()}
    favourite = max(sorted(eta), key=lambda v: eta[v])
    assert f"the learner starts from member {favourite} " in said
    assert rows[1]["learner_start_node"] == favourite
    [weights] = started
    member = r.load_member_state(favourite)
    assert set(weights[LEARNER]) == set(member)
    for name, value in member.items():
        assert (weights[LEARNER][name] == value).all(), name

    # self-play has no population: its learner alone starts from the shipped favourite
    started.clear()
    said = train(run | {"method": "sp"}, tmp_path / "sp", capsys)
    assert f"the learner starts from member {favourite} of the shipped population tiny-s0" in said
    sp = RunDir(tmp_path / "sp")
    assert sp.completed() == [1] and sp.metrics_rows()[0]["learner_start_node"] == favourite
    [weights] = started
    for name, value in member.items():
        assert (weights[LEARNER][name] == value).all(), name

    # a common start (`pretrain.start_agent`): the shipped population's last node, whatever
    # the population the run trains beside
    started.clear()
    common = run | {"method": "sp", "pretrain": {"population": "none", "start_agent": "tiny-s0"}}
    said = train(common, tmp_path / "common", capsys)
    last = max(eta)
    assert f"the learner starts from tiny-s0's node {last} (member; the common start" in said
    [weights] = started
    for name, value in r.load_member_state(last).items():
        assert (weights[LEARNER][name] == value).all(), name
    # and PBT's agents, every one a copy of it
    pbt_start = common | {"method": "pbt", "generations": 0}
    said = train(pbt_start, tmp_path / "pbt-common", capsys)
    assert f"3 agents, each a copy of tiny-s0's node {last} (member; the common start" in said
    copies = RunDir(tmp_path / "pbt-common")
    for node in range(3):
        for name, value in r.load_member_state(last).items():
            assert (copies.load_member_state(node)[name] == value).all(), (node, name)

    # PBT may seat MEP's members as its starting agents; generation 1 trains agent 0
    train(run | {"method": "pbt"}, tmp_path / "pbt", capsys)
    pbt = RunDir(tmp_path / "pbt")
    assert pbt.completed() == [0, 1] and pbt.metrics_rows()[0]["adopted_from"] == "tiny-s0"
    assert "learner_start_node" not in pbt.metrics_rows()[1]  # it trains agent 0, not a start
    extra = pbt.read_json(1, "state.json")["population"]["extra"]
    assert set(extra["agent_hyper"]) == {"0", "1", "2"} and set(extra["agent_scores"]) == {"0"}

    # a run with another reward takes the members and weighs G_0 under its own reward
    env = smoke["env"] | {"reward": smoke["env"].get("reward", {}) | {"collision": 30.0}}
    other = smoke | {"env": env, "pretrain": {"population": "tiny-s0"}, "generations": 0}
    said = train(other, tmp_path / "reweighed", capsys)
    assert "G_0 weighed under this run's scenario (env.reward.collision differ)" in said
    again = RunDir(tmp_path / "reweighed")
    assert again.metrics_rows()[0]["adopted_from"] == "tiny-s0"
    for entry in manifest["members"].values():  # the same members, weighed again
        copied, shipped_export = (
            x.load_member_export(entry["node"]) for x in (again, shipped.RunDir(folder))
        )
        for a, b in zip(copied["weights"], shipped_export["weights"], strict=True):
            assert (a == b).all()
    weights_then = {tuple(e["nodes"]): e["team_return"] for e in r.read_json(0, "edges.json")}
    weights_now = {tuple(e["nodes"]): e["team_return"] for e in again.read_json(0, "edges.json")}
    assert set(weights_now) == set(weights_then) and weights_now != weights_then
    for entry in manifest["members"].values():
        assert (r.root / entry["file"]).read_bytes() == (folder / entry["file"]).read_bytes()

    # a build that trains on from tiny-s0's members (`pretrain.members_from`), under another
    # reward: its members start as tiny-s0's, node k's weights as member k's
    started.clear()
    on = other | {"pretrain": {"members_from": "tiny-s0", "env_steps": 500}}
    (configs / "tiny-s1.yaml").write_text(yaml.safe_dump(on))
    assert populations.main(["build", "tiny-s1", "--episodes", "4"]) == 0
    said = capsys.readouterr().out
    assert "pre-train: the members start from tiny-s0's nodes 0, 1, 2 (built at commit" in said
    first = started[0]
    assert sorted(first) == ["member_0", "member_1", "member_2"]
    for node in range(3):
        for name, value in r.load_member_state(node).items():
            assert (first[f"member_{node}"][name] == value).all(), (node, name)
    trained_on = RunDir(tmp_path / "runs" / "tiny-s1")
    assert trained_on.metrics_rows()[0]["pretrain_env_steps"] >= 500
    assert populations.main(["show", "tiny-s1"]) == 0
    assert "its members started from tiny-s0's" in capsys.readouterr().out
    for node in range(3):  # and then trained: not tiny-s0's any more
        assert any(
            (a != b).any()
            for a, b in zip(
                trained_on.load_member_export(node)["weights"],
                r.load_member_export(node)["weights"],
                strict=True,
            )
        )
    four = on | {"population": smoke["population"] | {"initial_size": 4}}
    with pytest.raises(
        shipped.PopulationError, match="tiny-s0 holds 3 members; this build trains 4"
    ):
        train(four, tmp_path / "four", capsys)

    def refused(patch: dict, folder_used=folder) -> str:
        config = RunConfig.from_dict(smoke | {"pretrain": {"population": str(folder_used)}} | patch)
        with pytest.raises(shipped.PopulationError) as err:
            Trainer(config, tmp_path / f"refused-{len(list(tmp_path.iterdir()))}").fit()
        return str(err.value)

    narrow = {"oracle": smoke["oracle"] | {"hidden": [16, 16]}}
    assert "hidden [32, 32], the run's [16, 16]" in refused(narrow)
    assert "built by 'mep' pre-training" in refused({"method": "fcp", "fcp": {"agents": 1}})
    broken = tmp_path / "broken"
    shutil.copytree(folder, broken)
    export = broken / manifest["members"]["node_1"]["file"]
    export.write_bytes(export.read_bytes() + b"x")
    assert f"{export} has sha256" in refused({}, broken)
    # a pool's member passed off as a population's (its hash recorded, so only the pool
    # check stands between it and training)
    pooled = tmp_path / "pooled"
    shutil.copytree(folder, pooled)
    entry = manifest["members"]["node_2"]
    shutil.copyfile(POOLS_DIR / "validation" / "sp-v1.pt", pooled / entry["file"])
    forged = json.loads((pooled / "manifest.json").read_text())
    forged["members"]["node_2"]["sha256"] = shipped.sha256(pooled / entry["file"])
    (pooled / "manifest.json").write_text(json.dumps(forged))
    assert "member node_2 is pool member validation/sp-v1" in refused({}, pooled)
    assert populations.main(["show", str(folder)]) == 0
    assert "as copies: success" in capsys.readouterr().out


# ---- a new method: one class (here, in this file) and one registry line --------------------
@dataclass(frozen=True)
class FavouriteConfig:
    """The toy method's own config section."""

    slot: int = 0

    def validate(self) -> None:
        require(self.slot >= 0, "favourite.slot", "an integer >= 0", self.slot)


@dataclass(frozen=True)
class AlwaysTheFavourite:
    """Rules: every partner is the member in one slot; the learner never joins."""

    slot: int

    def setup(self, population: Population) -> None:
        pass

    def phi(self, population: Population, exclude_slot=None) -> dict[int, float]:
        return {population.slot_member(self.slot): 1.0}

    def values(self, population: Population) -> dict[int, float | None]:
        return dict.fromkeys(population.members)

    def decide(self, population: Population, slot, rng) -> Decision:
        return population.decide(admit=False)


class Favourite(Method):
    origin = Origin(shared=True)  # MEP's population, as Method builds it by default
    section = ("favourite", FavouriteConfig)

    def may_join(self) -> bool:
        return False

    def rules(self, config: RunConfig) -> AlwaysTheFavourite:
        return AlwaysTheFavourite(config.favourite.slot)


def test_a_new_method_is_one_class_and_one_registry_line(tmp_path, capsys, mep_zero):
    """A method written here, outside the package, registered with one line, trains a
    generation through the one trainer: its own section is read, the coordinator draws by
    its rules (φ all on the favourite) and the Oracle seats what the coordinator planned."""
    from ray import cloudpickle

    cloudpickle.register_pickle_by_value(sys.modules[__name__])  # for the coordinator actor
    register(Favourite("favourite", "a toy: every partner is one member"))
    try:
        smoke = yaml.safe_load(SMOKE.read_text())
        out = tmp_path / "favourite"
        config = smoke | {"method": "favourite", "favourite": {"slot": 2}}
        said = train(config, out, capsys, adopt_from=(mep_zero,))
        assert "gen 0: adopted from hola" in said  # the same G_0 as hola's, built once
        r = RunDir(out)
        assert r.completed() == [0, 1]
        assert r.read_json(1, "phi.json") == {"2": 1.0}  # node 2 sits in slot 2
        assert "population fixed (favourite: a best response" in said
        assert r.metrics_rows()[1]["accepted"] == 0
        with pytest.raises(ConfigError, match="favourite.slot must be an integer"):
            RunConfig.from_dict({"method": "favourite", "favourite": {"slot": "two"}})
    finally:
        unregister("favourite")
        cloudpickle.unregister_pickle_by_value(sys.modules[__name__])
    with pytest.raises(ConfigError, match="method must be one of"):
        RunConfig.from_dict({"method": "favourite"})
