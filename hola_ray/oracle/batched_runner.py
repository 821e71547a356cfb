"""`BatchedEnvRunner`: RLlib's multi-agent env runner, sampling the batched core directly.

RLlib's `MultiAgentEnvRunner` steps each sub-environment through the PettingZoo wrapper,
runs its connector pipelines per step and grows every `MultiAgentEpisode` one
`add_env_step` at a time. This runner keeps its interface (weights, φ mapping, metrics,
episodes for the same learner pipeline) but samples all `num_envs_per_env_runner` episodes
with one `BatchedPursuit` step, one forward pass per module over every row that module
plays, and builds each episode chunk in one go from numpy buffers when `sample` returns.

What it reproduces of the reference path (tested against `MultiAgentEnvRunner`): the
episodes' observations, actions, rewards, terminations and truncations, the agent → module
mapping (the runner's `policy_mapping_fn`, called once per agent at the start of every
episode), the module outputs kept for the learner (action distribution inputs and
log-probabilities), the unsquash of RLlib's [−1, 1] actions onto the Box, and the env
runner metrics the Oracle reads (env, agent and module steps; episode returns and lengths).
What it leaves out: per-step episode callbacks (`on_episode_step`), custom connectors (the
Oracle configures none), and lookback data in continued chunks (PPO does not read it).
"""

from __future__ import annotations

import time
from collections import defaultdict
from types import SimpleNamespace

import numpy as np
import torch
from ray.rllib.core.columns import Columns
from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner
from ray.rllib.env.multi_agent_episode import MultiAgentEpisode
from ray.rllib.env.single_agent_episode import SingleAgentEpisode
from ray.rllib.env.utils.infinite_lookback_buffer import InfiniteLookbackBuffer
from ray.rllib.utils.metrics import (
    NUM_AGENT_STEPS_SAMPLED,
    NUM_AGENT_STEPS_SAMPLED_LIFETIME,
    NUM_ENV_STEPS_SAMPLED,
    NUM_ENV_STEPS_SAMPLED_LIFETIME,
    NUM_EPISODES,
    NUM_EPISODES_LIFETIME,
    NUM_MODULE_STEPS_SAMPLED,
    NUM_MODULE_STEPS_SAMPLED_LIFETIME,
    WEIGHTS_SEQ_NO,
)

from hola_ray.env.config import PursuitConfig
from hola_ray.env.core import BatchedPursuit

SKIP = MultiAgentEpisode.SKIP_ENV_TS_TAG


class _Episode:
    """One sub-environment's episode while it runs: its id, who plays each slot, and where
    its current chunk began (env step within the episode, row of this sample's buffers)."""

    __slots__ = ("id_", "seed", "modules", "env_t_started", "agent_t_started", "row", "live")

    def __init__(self, id_: str, seed: int, modules: list[str], n_p: int) -> None:
        self.id_ = id_
        self.seed = seed
        self.modules = modules
        self.env_t_started = 0
        self.agent_t_started = np.zeros(n_p, dtype=np.int64)
        self.row = 0
        self.live = np.ones(n_p, dtype=bool)  # agents still acting at the chunk's start


class BatchedEnvRunner(MultiAgentEnvRunner):
    """A `MultiAgentEnvRunner` whose sub-environments are one `BatchedPursuit`."""

    def __init__(self, config, **kwargs) -> None:
        super().__init__(config=config, **kwargs)
        if self.env is None:  # the local runner beside remote ones holds no env
            return
        self._pursuit = PursuitConfig.from_dict(dict(self.config.env_config))
        self.agents = [f"pursuer_{i}" for i in range(self._pursuit.n_pursuers)]
        self.core = BatchedPursuit(self._pursuit, self.num_envs)
        seed = self.config.seed
        entropy = [int(seed), int(self.worker_index)] if seed is not None else None
        self._rng = np.random.default_rng(np.random.SeedSequence(entropy))
        self._episodes: list[_Episode | None] = [None] * self.num_envs
        self._obs_space = self.env.unwrapped.envs[0].unwrapped.get_observation_space(self.agents[0])
        self._act_space = self.env.unwrapped.envs[0].unwrapped.get_action_space(self.agents[0])
        self._low = float(self._act_space.low[0])
        self._high = float(self._act_space.high[0])
        # who plays each seat of each sub-environment: an index into _module_ids
        self._seat = np.zeros((self.num_envs, len(self.agents)), dtype=np.int64)
        self._module_ids: list[str] = []

    # ---- episodes -----------------------------------------------------------------------
    def _start(self, mask: np.ndarray) -> None:
        """Reset the sub-environments in mask with fresh seeds and start their episodes."""
        idx = np.flatnonzero(mask)
        if not idx.size:
            return
        seeds = self._rng.integers(0, 2**63 - 1, size=idx.size, dtype=np.int64)
        self.core.reset(seeds=seeds, mask=mask)
        mapping = self.config.policy_mapping_fn
        for b, seed in zip(idx, seeds, strict=True):
            eid = self._rng.bytes(16).hex()
            stub = SimpleNamespace(id_=eid)
            modules = [mapping(agent, stub) for agent in self.agents]
            self._episodes[b] = _Episode(eid, int(seed), modules, len(self.agents))
            for i, mid in enumerate(modules):
                if mid not in self._module_ids:
                    self._module_ids.append(mid)
                self._seat[b, i] = self._module_ids.index(mid)

    # ---- sampling -----------------------------------------------------------------------
    def _sample(
        self,
        *,
        num_timesteps: int | None = None,
        num_episodes: int | None = None,
        explore: bool,
        random_actions: bool = False,
        force_reset: bool = False,
    ) -> list[MultiAgentEpisode]:
        if random_actions:
            raise NotImplementedError("BatchedEnvRunner samples from its modules only")
        B = self.num_envs
        for mid in self.module.keys():
            self.module[mid].eval()  # they only act here; PPO trains the learner's copies
        if force_reset or num_episodes is not None or self._needs_initial_reset:
            self._ongoing_episodes_for_metrics.clear()
            self._start(np.ones(B, dtype=bool))
            self._needs_initial_reset = False
        if num_episodes is not None:
            self._needs_initial_reset = True
        steps = -(-num_timesteps // B) if num_timesteps is not None else None
        buf = _Buffers(self.core, steps or self._pursuit.horizon + 1)
        done_chunks: list[MultiAgentEpisode] = []
        ended_episodes = 0
        s = 0
        for e in self._episodes:
            e.row = 0
        while (s < steps) if steps is not None else (ended_episodes < num_episodes):
            if s == buf.capacity:
                buf.grow()
            live = self.core.pursuer_active & ~self.core.done[:, None]
            buf.obs[s] = self.core.obs
            buf.live[s] = live
            self._act(buf, s, live, explore)
            low, high = self._low, self._high
            to_env = low + (buf.actions[s, :, :, 0] + 1.0) * (0.5 * (high - low))
            result = self.core.step(np.clip(to_env, low, high))
            buf.next_obs[s] = result.obs
            buf.rewards[s] = result.reward
            buf.disabled[s] = result.disabled
            buf.truncated[s] = result.truncated
            ended = result.terminated | result.truncated
            for b in np.flatnonzero(ended):
                done_chunks.append(self._chunk(buf, b, s + 1, done=True))
                self._log_done(done_chunks[-1])
                ended_episodes += 1
            if ended.any():
                self._start(ended)
                for b in np.flatnonzero(ended):
                    self._episodes[b].row = s + 1
            s += 1
        self._log_steps(buf, s)
        chunks = list(done_chunks)
        if num_episodes is not None:
            return chunks
        for b, e in enumerate(self._episodes):
            if e.row >= s:  # just started: nothing in it yet
                continue
            chunk = self._chunk(buf, b, s, done=False)
            self._ongoing_episodes_for_metrics[e.id_].append(chunk)
            chunks.append(chunk)
            # the next chunk continues where this one ends
            rows = slice(e.row, s)
            acted = buf.live[rows, b].sum(axis=0)
            e.agent_t_started += acted
            e.env_t_started += s - e.row
            e.live = self.core.pursuer_active[b].copy()
        return chunks

    def _act(self, buf: _Buffers, s: int, live: np.ndarray, explore: bool) -> None:
        """Actions, log-probabilities and distribution inputs for every live agent at row s,
        one forward pass per module."""
        seat = np.where(live, self._seat, -1).ravel()
        obs = buf.obs[s].reshape(-1, buf.obs.shape[-1])
        actions = buf.actions[s].reshape(-1, 1)
        logp = buf.logp[s].reshape(-1)
        inputs = buf.dist_inputs[s].reshape(-1, buf.dist_inputs.shape[-1])
        with torch.no_grad():
            for m in np.unique(seat[seat >= 0]):
                rows = np.flatnonzero(seat == m)
                mid = self._module_ids[m]
                buf.module_steps[mid] += len(rows)
                module = self.module[mid]
                batch = {Columns.OBS: torch.from_numpy(obs[rows])}
                # What `forward_exploration` / `forward_inference` run, without their
                # train → eval → train switch per call (the modules are in eval mode)
                if explore:
                    out = module._forward_exploration(batch)
                    dist_cls = module.get_exploration_action_dist_cls()
                else:
                    out = module._forward_inference(batch)
                    dist_cls = module.get_inference_action_dist_cls()
                din = out[Columns.ACTION_DIST_INPUTS]
                if Columns.ACTIONS in out:
                    act = out[Columns.ACTIONS]
                    lp = out.get(Columns.ACTION_LOGP)
                else:
                    dist = dist_cls.from_logits(din)
                    if not explore:
                        dist = dist.to_deterministic()
                    act = dist.sample()
                    lp = dist.logp(act)
                actions[rows] = act.numpy().reshape(-1, 1)
                logp[rows] = 0.0 if lp is None else lp.numpy()
                inputs[rows] = din.numpy()

    # ---- episode chunks -----------------------------------------------------------------
    def _chunk(self, buf: _Buffers, b: int, stop: int, done: bool) -> MultiAgentEpisode:
        """The chunk of sub-environment b from its episode's `row` to row `stop`."""
        e = self._episodes[b]
        rows = slice(e.row, stop)
        n = stop - e.row
        live = buf.live[rows, b]  # [n, n_p]
        episode = MultiAgentEpisode(
            id_=e.id_,
            observation_space={a: self._obs_space for a in self.agents},
            action_space={a: self._act_space for a in self.agents},
            agent_module_ids={a: e.modules[i] for i, a in enumerate(self.agents) if e.live[i]},
            agent_to_module_mapping_fn=self.config.policy_mapping_fn,
            len_lookback_buffer=0,
        )
        episode.env_t_started = e.env_t_started
        episode.env_t = e.env_t_started + n
        truncated = bool(done and buf.truncated[stop - 1, b])
        for i, agent in enumerate(self.agents):
            if not e.live[i]:
                continue
            k = int(live[:, i].sum())  # steps the agent acted in this chunk
            t0 = int(e.agent_t_started[i])
            disabled = bool(k and buf.disabled[e.row + k - 1, b, i])
            obs = np.concatenate(
                [buf.obs[e.row, b, i][None], buf.next_obs[e.row : e.row + k, b, i]]
            )
            sa = SingleAgentEpisode(
                id_=f"{e.id_}/{agent}",
                agent_id=agent,
                module_id=e.modules[i],
                multi_agent_episode_id=e.id_,
                observations=obs.copy(),
                observation_space=self._obs_space,
                infos=[{} for _ in range(k + 1)],
                actions=buf.actions[e.row : e.row + k, b, i].copy(),
                action_space=self._act_space,
                rewards=buf.rewards[e.row : e.row + k, b, i].copy(),
                extra_model_outputs={
                    Columns.ACTION_DIST_INPUTS: buf.dist_inputs[e.row : e.row + k, b, i].copy(),
                    Columns.ACTION_LOGP: buf.logp[e.row : e.row + k, b, i].copy(),
                    WEIGHTS_SEQ_NO: np.full(k, self._weights_seq_no, dtype=np.int64),
                },
                # As RLlib records PursuitEnv: an agent that is done when every agent is
                # done counts as terminated, also at the horizon (so no value bootstrap).
                terminated=disabled or done,
                truncated=truncated and k == n,
                t_started=t0,
                len_lookback_buffer=0,
            )
            episode.agent_episodes[agent] = sa
            episode.agent_t_started[agent] = t0
            mapping = list(range(t0, t0 + k + 1)) + [SKIP] * (n - k)
            episode.env_t_to_agent_t[agent] = InfiniteLookbackBuffer(data=mapping, lookback=0)
        # As `MultiAgentEpisode.add_env_step` has it: an episode whose agents are all done
        # is terminated, also when the horizon truncated it.
        episode.is_terminated = done
        episode.is_truncated = truncated
        episode.custom_data["seed"] = e.seed  # replays as PursuitEnv.reset(seed=…)
        now = time.perf_counter()
        episode._start_time = episode._last_step_time = now
        return episode

    # ---- metrics ------------------------------------------------------------------------
    def _log_steps(self, buf: _Buffers, steps: int) -> None:
        """Env, agent and module step counts of this sample, logged once."""
        env_steps = steps * self.num_envs  # an episode that ends is reset at once
        self.metrics.log_value(NUM_ENV_STEPS_SAMPLED, env_steps, reduce="sum")
        self.metrics.log_value(
            NUM_ENV_STEPS_SAMPLED_LIFETIME, env_steps, reduce="lifetime_sum", with_throughput=True
        )
        self._log_env_steps(metric=self._metrics_num_env_steps_sampled, num_steps=env_steps)
        per_agent = buf.live[:steps].sum(axis=(0, 1))
        for i, agent in enumerate(self.agents):
            self.metrics.log_value(
                (NUM_AGENT_STEPS_SAMPLED, agent), int(per_agent[i]), reduce="sum"
            )
            self.metrics.log_value(
                (NUM_AGENT_STEPS_SAMPLED_LIFETIME, agent), int(per_agent[i]), reduce="lifetime_sum"
            )
        for mid, count in buf.module_steps.items():
            self.metrics.log_value((NUM_MODULE_STEPS_SAMPLED, mid), count, reduce="sum")
            self.metrics.log_value(
                (NUM_MODULE_STEPS_SAMPLED_LIFETIME, mid), count, reduce="lifetime_sum"
            )

    def _log_done(self, episode: MultiAgentEpisode) -> None:
        self.metrics.log_value(NUM_EPISODES, 1, reduce="sum")
        self.metrics.log_value(NUM_EPISODES_LIFETIME, 1, reduce="lifetime_sum")
        self._done_episodes_for_metrics.append(episode)


class _Buffers:
    """One `sample` call's data, row s = the s-th vector step: what each agent saw and did."""

    def __init__(self, core: BatchedPursuit, capacity: int) -> None:
        B, n_p, dim = core.obs.shape
        self.capacity = capacity
        self.obs = np.zeros((capacity, B, n_p, dim), np.float32)
        self.next_obs = np.zeros_like(self.obs)
        self.live = np.zeros((capacity, B, n_p), bool)
        self.actions = np.zeros((capacity, B, n_p, 1), np.float32)
        self.logp = np.zeros((capacity, B, n_p), np.float32)
        self.dist_inputs = np.zeros((capacity, B, n_p, 2), np.float32)
        self.rewards = np.zeros((capacity, B, n_p), np.float64)
        self.disabled = np.zeros((capacity, B, n_p), bool)
        self.truncated = np.zeros((capacity, B), bool)
        self.module_steps: dict[str, int] = defaultdict(int)

    def grow(self) -> None:
        for name in (
            "obs",
            "next_obs",
            "live",
            "actions",
            "logp",
            "dist_inputs",
            "rewards",
            "disabled",
            "truncated",
        ):
            a = getattr(self, name)
            setattr(self, name, np.concatenate([a, np.zeros_like(a)]))
        self.capacity *= 2
