"""Env steps per second: `PursuitEnv` and the batched core against PettingZoo MPE simple_tag_v3.

Not a test. Every figure is measured in this run on this machine:
- PettingZoo API, random actions from `action_space.sample()`, reset when the episode ends:
  `PursuitEnv` (3 pursuers, 2 evaders, 5 bars) vs MPE `simple_tag_v3` (3 adversaries,
  2 good agents, 5 obstacles, continuous actions).
- The batched core at B = 1, 64, 1024, 4096: evader and a Greedy team included, finished
  episodes reset in place; one batched step counts as B env steps.
The last line is one JSON object.

    python benchmarks/env_speed.py [--seconds 3]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from hola_ray.env import BatchedPursuit, PursuitConfig
from hola_ray.env.pettingzoo_env import PursuitEnv
from hola_ray.policies import Greedy


def pettingzoo_steps_per_s(env, seconds: float) -> float:
    """Steps/s of a ParallelEnv under random actions, resetting finished episodes."""
    env.reset(seed=0)
    for agent in env.possible_agents:
        env.action_space(agent).seed(0)
    for _ in range(50):  # warm-up (compilation, caches)
        env.step({a: env.action_space(a).sample() for a in env.agents})
        if not env.agents:
            env.reset()
    steps, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        env.step({a: env.action_space(a).sample() for a in env.agents})
        steps += 1
        if not env.agents:
            env.reset()
    return steps / elapsed


def batched_steps_per_s(config: PursuitConfig, batch: int, seconds: float) -> float:
    """Env steps/s of the batched core with a Greedy team choosing every action."""
    core = BatchedPursuit(config, batch)
    core.reset(seeds=np.arange(batch))
    policy = Greedy(config)

    def one_step() -> None:
        actions = policy.act(core.obs.reshape(-1, config.obs_dim)).reshape(batch, -1)
        core.step(actions)
        if core.done.any():
            core.reset(mask=core.done)

    for _ in range(20):
        one_step()
    steps, start = 0, time.perf_counter()
    while (elapsed := time.perf_counter() - start) < seconds:
        one_step()
        steps += 1
    return steps * batch / elapsed


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="timing window per figure")
    args = parser.parse_args()

    from mpe2 import simple_tag_v3

    config = PursuitConfig()
    mpe = simple_tag_v3.parallel_env(
        num_good=2, num_adversaries=3, num_obstacles=5, max_cycles=1000, continuous_actions=True
    )
    mpe_rate = pettingzoo_steps_per_s(mpe, args.seconds)
    ours = pettingzoo_steps_per_s(PursuitEnv(config), args.seconds)
    print(f"MPE simple_tag_v3 (PettingZoo API)   {mpe_rate:>12,.0f} env steps/s")
    print(
        f"PursuitEnv        (PettingZoo API)   {ours:>12,.0f} env steps/s   "
        f"{ours / mpe_rate:6.1f}× MPE"
    )
    batched = {}
    for batch in (1, 64, 1024, 4096):
        batched[batch] = batched_steps_per_s(config, batch, args.seconds)
        print(
            f"batched core B={batch:<5} + Greedy       {batched[batch]:>12,.0f} env steps/s   "
            f"{batched[batch] / mpe_rate:6.0f}× MPE"
        )
    print(
        json.dumps(
            {
                "pettingzoo_env_steps_per_s": round(ours, 1),
                "mpe_simple_tag_env_steps_per_s": round(mpe_rate, 1),
                "pettingzoo_over_mpe": round(ours / mpe_rate, 2),
                "batched_env_steps_per_s": {str(b): round(v, 1) for b, v in batched.items()},
                "batched_1024_over_mpe": round(batched[1024] / mpe_rate, 1),
            }
        )
    )


if __name__ == "__main__":
    main()
