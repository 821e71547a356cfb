"""The batched env runner against the reference path: its episodes replay exactly in
`PursuitEnv` and equal the episodes RLlib's own bookkeeping (`MultiAgentEpisode.add_env_step`,
as `MultiAgentEnvRunner` does it) builds from that replay, chunk cuts included; and a runner
RLlib recreates samples partners from the pushed φ again. And budgets on the learner's own
experience (the last tests): at `oracle.budget: learner_samples` the self-play learner (every
seat) and a single learner (one seat) consume the same number of their own transitions and
take the same number of gradient steps; at env_steps self-play's learner gets about n_p times
the data, counted from what the learner consumed and checked against what the env runners
sampled for it. One Ray session for the module."""

from __future__ import annotations

import os
import sys
import time
from collections import defaultdict

import numpy as np
import pytest
import ray
import torch
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode

from hola_ray.env.pettingzoo_env import PursuitEnv
from hola_ray.methods.config import RunConfig
from hola_ray.oracle import LEARNER, member_module

CONFIG = RunConfig.from_dict(
    {
        "env": {"horizon": 50, "reward": {"obstacle_penalty": 0.5, "teammate_penalty": 0.5}},
        "oracle": {
            "hidden": [16, 16],
            "train_batch": 300,
            "minibatch": 100,
            "epochs": 1,
            "envs_per_runner": 6,
            "env_steps": 300,
            "sampler": "batched",
        },
        "population": {"max_size": 3, "initial_size": 3, "top_m": 1},
    }
)
# The helpers below run inside the env runner actors, which cannot import this test file.
ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])
COLUMNS = ("obs", "actions", "rewards", "action_dist_inputs", "action_logp")


@pytest.fixture(scope="module")
def oracle(ray_session):
    o = CONFIG.strategy.make_oracle(CONFIG)
    o.train(300, progress=False)
    yield o
    o.stop()


def sample_chunks(runner, calls: int, steps: int):
    """`calls` successive samples of `steps` env steps each, from fresh episodes: per
    episode id, its chunks in order as plain data (episodes are not sent back whole)."""
    out = defaultdict(list)
    for k in range(calls):
        for ep in runner.sample(num_timesteps=steps, force_reset=k == 0):
            ep.validate()
            agents = {}
            for aid, sa in ep.agent_episodes.items():
                n = len(sa)
                agents[aid] = {
                    "module": sa.module_id,
                    "t_started": sa.t_started,
                    "terminated": sa.is_terminated,
                    "truncated": sa.is_truncated,
                    "obs": np.asarray(sa.get_observations(slice(0, n + 1))),
                    "actions": np.asarray(sa.get_actions(slice(0, n))),
                    "rewards": np.asarray(sa.get_rewards(slice(0, n))),
                    "action_dist_inputs": np.asarray(
                        sa.get_extra_model_outputs("action_dist_inputs", slice(0, n))
                    ),
                    "action_logp": np.asarray(
                        sa.get_extra_model_outputs("action_logp", slice(0, n))
                    ),
                }
            out[ep.id_].append(
                {
                    "seed": ep.custom_data.get("seed"),
                    "env_t_started": ep.env_t_started,
                    "env_t": ep.env_t,
                    "len": len(ep),
                    "done": ep.is_done,
                    "terminated": ep.is_terminated,
                    "truncated": ep.is_truncated,
                    "return": ep.get_return(),
                    "agents": agents,
                }
            )
    return dict(out)


def joined(chunks):
    """One agent's data over an episode's chunks, in order."""
    agents = defaultdict(lambda: defaultdict(list))
    for chunk in chunks:
        for aid, data in chunk["agents"].items():
            cols = agents[aid]
            cols["obs"].append(data["obs"] if not cols["obs"] else data["obs"][1:])
            for col in COLUMNS[1:]:
                cols[col].append(data[col])
            cols["module"], cols["terminated"] = data["module"], data["terminated"]
            cols["truncated"] = data["truncated"]
    return {
        aid: {k: (np.concatenate(v) if isinstance(v, list) else v) for k, v in cols.items()}
        for aid, cols in agents.items()
    }


def replay(seed: int, actions: dict[str, np.ndarray], dist_inputs, logp, modules, env=None):
    """The episode of `seed` played in `PursuitEnv` with the recorded actions (RLlib's
    [−1, 1], unsquashed onto the Box as RLlib does), recorded the way RLlib's
    `MultiAgentEnvRunner` records it; and the env's end-of-episode infos. Each agent's
    actions are indexed by its own steps (a teammate that joins late starts at 0)."""
    env = PursuitEnv(env or CONFIG.env)
    obs, infos = env.reset(seed=seed)
    episode = MultiAgentEpisode(agent_module_ids=modules)
    episode.add_env_reset(observations=obs, infos=infos)
    own = defaultdict(int)
    while env.agents:
        live = list(env.agents)
        act = {a: actions[a][own[a]] for a in live}
        to_env = {a: np.clip((act[a] + 1.0) / 2.0, 0.0, 1.0) for a in live}
        extra = {
            a: {"action_dist_inputs": dist_inputs[a][own[a]], "action_logp": logp[a][own[a]]}
            for a in live
        }
        for a in live:
            own[a] += 1
        obs, rewards, terms, truncs, infos = env.step(to_env)
        # as RLlib's ParallelPettingZooEnv wrapper reports the episode's end
        terms["__all__"] = all(terms.values())
        truncs["__all__"] = all(truncs.values())
        episode.add_env_step(
            observations=obs,
            actions=act,
            rewards=rewards,
            infos=infos,
            terminateds=terms,
            truncateds=truncs,
            extra_model_outputs=extra,
        )
        end_infos = infos
    episode = episode.to_numpy()
    if episode.is_truncated:  # the one deliberate difference: the horizon truncates
        episode.is_terminated = False
        for sa in episode.agent_episodes.values():
            if sa.is_truncated:
                sa.is_terminated = False
    return episode, end_infos


def replayed_alike(oracle, env) -> set:
    """Sample 8 calls of 150 env steps on every remote runner, replay each finished episode
    in `PursuitEnv` with its recorded actions, and hold the runner's chunks to RLlib's own
    bookkeeping of the replay; the outcomes seen (success, collision, truncated)."""
    # 6 envs × 25 steps per call with a 50-step horizon: most episodes span 2–3 chunks
    runs = oracle.algo.env_runner_group.foreach_env_runner(
        lambda r: sample_chunks(r, calls=8, steps=150), local_env_runner=False
    )
    episodes = {k: v for run in runs for k, v in run.items()}
    finished = {k: v for k, v in episodes.items() if v[-1]["done"]}
    assert len(finished) >= 12
    assert sum(len(v) > 1 for v in finished.values()) >= 6  # cut and continued
    outcomes = set()
    for chunks in finished.values():
        starts = [c["env_t_started"] for c in chunks]
        ends = [c["env_t"] for c in chunks]
        assert starts[0] == 0 and starts[1:] == ends[:-1]  # chunks tile the episode
        assert not any(c["done"] for c in chunks[:-1])
        data = joined(chunks)
        modules = {aid: d["module"] for aid, d in data.items()}
        assert sorted(modules.values()).count(LEARNER) == 1
        ref, infos = replay(
            chunks[0]["seed"],
            {a: d["actions"] for a, d in data.items()},
            {a: d["action_dist_inputs"] for a, d in data.items()},
            {a: d["action_logp"] for a, d in data.items()},
            modules,
            env,
        )
        assert sum(c["len"] for c in chunks) == len(ref)
        assert chunks[-1]["terminated"] == ref.is_terminated
        assert chunks[-1]["truncated"] == ref.is_truncated
        total = sum(c["return"] for c in chunks)
        np.testing.assert_allclose(total, ref.get_return(), rtol=1e-6)
        any_info = next(iter(infos.values()))
        np.testing.assert_allclose(total, any_info["team_return"], rtol=1e-6)
        assert len(ref) == any_info["length"]
        outcomes.add((any_info["success"], any_info["collision"], ref.is_truncated))
        assert set(ref.agent_episodes) == set(data)
        for aid, sa in ref.agent_episodes.items():
            n = len(sa)
            mine = data[aid]
            assert sa.module_id == mine["module"]
            assert (sa.is_terminated, sa.is_truncated) == (mine["terminated"], mine["truncated"])
            np.testing.assert_array_equal(sa.get_observations(slice(0, n + 1)), mine["obs"])
            np.testing.assert_array_equal(sa.get_actions(slice(0, n)), mine["actions"])
            np.testing.assert_allclose(sa.get_rewards(slice(0, n)), mine["rewards"], rtol=1e-12)
            for col in ("action_dist_inputs", "action_logp"):
                np.testing.assert_array_equal(
                    sa.get_extra_model_outputs(col, slice(0, n)), mine[col]
                )
    return outcomes


def test_episodes_replay_in_pursuit_env_and_match_rllibs_bookkeeping(oracle):
    oracle.set_phi({member_module(0): 1.0, member_module(2): 2.0})
    # the comparison covered episodes that ended in different ways
    assert len(replayed_alike(oracle, CONFIG.env)) >= 2


OPEN = RunConfig.from_dict(
    CONFIG.to_dict()
    | {
        "env": CONFIG.env.to_dict()
        | {"team": {"present": [1, 3], "changes": 3, "window": [0.05, 0.8]}}
    }
)


def test_teammates_who_join_and_leave_replay_as_rllib_records_them(ray_session):
    """A team of 1–3 of 3 that changes three times an episode: a teammate that joins starts
    its own agent episode at its first observation, one that leaves ends its own, and the
    learner keeps seat 0; every chunk equals RLlib's bookkeeping of the replay."""
    o = OPEN.strategy.make_oracle(OPEN)
    try:
        o.set_phi({member_module(0): 1.0, member_module(1): 1.0})
        assert len(replayed_alike(o, OPEN.env)) >= 1
        seats = o.algo.env_runner_group.foreach_env_runner(
            lambda r: [e.modules.index(LEARNER) for e in r._episodes if LEARNER in e.modules],
            local_env_runner=False,
        )
        assert {s for run in seats for s in run} == {0}
    finally:
        o.stop()


def test_a_recreated_runner_samples_partners_from_the_pushed_phi(oracle):
    target = member_module(1)
    oracle.set_phi({target: 1.0}, salt=3)
    group = oracle.algo.env_runner_group
    (worker_id,) = group.healthy_worker_ids()
    actor = group._worker_manager.actors()[worker_id]

    def die(runner):
        os._exit(1)

    # The runner dies during a call, as in a crash mid-sample: RLlib takes it out of service.
    group.foreach_env_runner(die, local_env_runner=False)
    assert worker_id not in group.healthy_worker_ids()
    for _ in range(240):  # Ray restarts the actor process in the background
        try:
            ray.get(actor.apply.remote(lambda r: None), timeout=10)
            break
        except ray.exceptions.RayError:
            time.sleep(0.5)
    # The next training iteration brings it back into service (RLlib's restore and its
    # on_env_runners_recreated callback), then samples from it.
    oracle.train(300, progress=False)
    assert worker_id in group.healthy_worker_ids()

    def modules(runner):
        eps = runner.sample(num_timesteps=600, force_reset=True)
        return [ep.module_for(a) for ep in eps for a in ep.agent_ids]

    (seen,) = group.foreach_env_runner(modules, local_env_runner=False)
    assert seen and set(seen) == {LEARNER, target}


def test_the_partner_stack_plays_each_partners_own_actor():
    """The frozen partners' batched forward pass gives, row by row, what each partner's own
    actor (`MLPPolicy`, which equals RLlib's module) gives, for uneven groups and an absent
    partner."""
    import torch

    from hola_ray.oracle.batched_runner import _PartnerStack
    from hola_ray.oracle.distribution import BetaTurn
    from hola_ray.policies.learned import FORMAT, MLPPolicy

    env = CONFIG.env
    features = CONFIG.oracle.model_features(CONFIG.env)
    dim = env.obs_dim + len(features["indices"])
    gen = torch.Generator().manual_seed(0)

    def actor():
        shapes = [(16, dim), (16, 16), (2, 16)]
        export = {
            "format": FORMAT,
            "dist": "beta",
            "weights": [torch.randn(s, generator=gen) * 0.5 for s in shapes],
            "biases": [torch.randn(s[0], generator=gen) * 0.1 for s in shapes],
            "activation": "tanh",
            "low": 0.0,
            "high": 1.0,
            "features": features,
        }
        return MLPPolicy(env, export)

    class Module:
        @staticmethod
        def get_inference_action_dist_cls():
            return BetaTurn

    actors = [actor() for _ in range(4)]
    stack = _PartnerStack.of({f"m{k}": (Module(), a) for k, a in enumerate(actors)})
    rng = np.random.default_rng(1)
    obs = rng.uniform(-1, 1, (40, env.obs_dim)).astype(np.float32)
    slot = rng.choice([0, 1, 3], size=40, p=[0.6, 0.3, 0.1])  # partner 2 plays no row
    got = stack.logits(stack.with_features(obs), slot)
    for k, a in enumerate(actors):
        rows = slot == k
        np.testing.assert_allclose(got[rows].numpy(), a.logits(obs[rows]).numpy(), atol=1e-6)
    # index of a runner's module ids → slot (−1: not a partner)
    assert stack.slots(["learner", "m3", "m0"]).tolist() == [-1, 3, 0]


def test_an_episode_cut_at_the_horizon_bootstraps_its_last_value(local_learner, oracle):
    """A hand-made episode of the learner, three steps of reward 1: cut at the horizon
    (truncated) its last value target is r + γ·V(s_3), the value of the observation it was
    cut at; ended (terminated) it is r alone. The same learner connector PPO trains with."""
    from ray.rllib.core.columns import Columns
    from ray.rllib.env.single_agent_episode import SingleAgentEpisode
    from ray.rllib.env.utils.infinite_lookback_buffer import InfiniteLookbackBuffer
    from ray.rllib.evaluation.postprocessing import Postprocessing

    learner = local_learner(oracle.algo)
    module = learner.module[LEARNER]
    rng = np.random.default_rng(5)
    obs = rng.uniform(-1, 1, (4, CONFIG.env.obs_dim)).astype(np.float32)
    gamma = CONFIG.oracle.gamma

    def last_target(truncated: bool) -> float:
        sa = SingleAgentEpisode(
            agent_id="pursuer_0",
            module_id=LEARNER,
            observations=list(obs),
            actions=[np.zeros(1, np.float32)] * 3,
            rewards=[1.0, 1.0, 1.0],
            extra_model_outputs={
                Columns.ACTION_DIST_INPUTS: [np.zeros(2, np.float32)] * 3,
                Columns.ACTION_LOGP: [np.float32(0.0)] * 3,
            },
            terminated=not truncated,
            truncated=truncated,
            len_lookback_buffer=0,
        )
        episode = MultiAgentEpisode(agent_module_ids={"pursuer_0": LEARNER})
        episode.agent_episodes["pursuer_0"] = sa
        episode.env_t_to_agent_t["pursuer_0"] = InfiniteLookbackBuffer(
            data=[0, 1, 2, 3], lookback=0
        )
        episode.env_t = 3
        episode.is_terminated, episode.is_truncated = not truncated, truncated
        batch = learner._learner_connector(
            rl_module=learner.module, batch={}, episodes=[episode], metrics=learner.metrics
        )
        targets = np.asarray(batch[LEARNER][Postprocessing.VALUE_TARGETS])
        mask = np.asarray(batch[LEARNER].get(Columns.LOSS_MASK, np.ones(len(targets), bool)))
        return float(targets[mask.astype(bool)][-1])

    with torch.no_grad():
        v_last = float(module.compute_values({Columns.OBS: torch.from_numpy(obs[3:])})[0])
    assert last_target(truncated=False) == pytest.approx(1.0, abs=1e-5)
    assert last_target(truncated=True) == pytest.approx(1.0 + gamma * v_last, abs=1e-5)
    assert abs(v_last) > 1e-3  # the bootstrap is visible


# ---- budgets on the learner's own experience --------------------------------------------
BUDGET = 2400
BATCH = 600


def budget_config(method: str, budget: str) -> RunConfig:
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


def train_to_budget(method: str, budget: str):
    run_config = budget_config(method, budget)
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
def budget_runs(ray_session):
    return {
        (m, b): train_to_budget(m, b)
        for m in ("sp", "hola")
        for b in ("learner_samples", "env_steps")
    }


def test_equal_learner_samples_and_gradient_steps_at_the_learner_samples_budget(budget_runs):
    sp, sp_sampled = budget_runs[("sp", "learner_samples")]
    one, one_sampled = budget_runs[("hola", "learner_samples")]
    for stats, sampled in ((sp, sp_sampled), (one, one_sampled)):
        assert stats.learner_samples == sampled  # every sampled learner step was consumed
        assert BUDGET <= stats.learner_samples < BUDGET + BATCH  # stops within one batch
    # self-play's batch spans a third of the env steps: the same data from fewer steps
    assert sp.env_steps < 0.5 * one.env_steps
    # a PPO update covers its batch `epochs` times in minibatches: equal batches, equal steps
    assert abs(sp.gradient_steps - one.gradient_steps) <= 2 * 2  # one batch's worth at most


def test_at_the_env_steps_budget_self_play_learns_from_every_seat(budget_runs):
    sp, _ = budget_runs[("sp", "env_steps")]
    one, _ = budget_runs[("hola", "env_steps")]
    assert sp.env_steps >= BUDGET and one.env_steps >= BUDGET
    assert sp.learner_samples > 2 * one.learner_samples  # n_p = 3 seats against one
