"""`ScenarioAdapter`: a policy trained for one team playing another (contract §6.2).

A policy reads the observation of the scenario it was trained in: so many evader triples,
so many teammate pairs (`hola_ray.config.layout.ObsLayout`). In a scenario whose observation
holds other counts, the adapter hands it the observation it knows:

- fewer evaders than it was trained with: the missing ones read as captured,
  (unobserved distance, 0, 0), exactly what it saw in training once an evader was caught;
- more evaders: the nearest it has slots for (a captured one reads as farthest);
- fewer teammates: the missing ones read as unobserved, (unobserved distance, 0), what it
  saw of a teammate out of range or crashed;
- more teammates: the nearest it has slots for.

The chosen ones keep their order in the observation (by seat), and the teammates' headings,
where the scenario observes them, follow their teammates. The nearest obstacle and its own
block are copied as they are. An adapted member is what it was trained to be, seeing the
part of a larger team it has room for; the results that seat one say so.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from hola_ray.config.scenario import PursuitConfig, TeamChangeConfig
from hola_ray.policies.base import Policy


def trained_scenario(config: PursuitConfig, n_pursuers: int, n_evaders: int) -> PursuitConfig:
    """`config` as a policy trained for `n_pursuers` vs `n_evaders` (no slots beyond them,
    the team kept whole) sees it: the scenario to build that policy in."""
    return dataclasses.replace(
        config,
        n_pursuers=n_pursuers,
        n_evaders=n_evaders,
        obs_pursuers=None,
        obs_evaders=None,
        team=TeamChangeConfig(),
    )


def _nearest(distance: np.ndarray, keep: int) -> np.ndarray:
    """[N, keep] indices of the `keep` smallest distances of each row, in their own order."""
    order = np.argsort(distance, axis=1, kind="stable")[:, :keep]
    return np.sort(order, axis=1)


class ScenarioAdapter(Policy):
    """`policy` (built for the scenario it was trained in, `policy.config`) playing `config`,
    whose observation holds other numbers of evaders or teammates (module docstring)."""

    def __init__(self, config: PursuitConfig, policy: Policy) -> None:
        super().__init__(config)
        if policy.config.observe_headings != config.observe_headings:
            given = "with" if policy.config.observe_headings else "without"
            raise ValueError(
                f"{policy.name} was trained {given} the teammates' headings; this scenario differs"
            )
        self.policy = policy
        self.name = policy.name
        self.source, self.target = config.layout, policy.config.layout
        self.far = np.float32(config.unobserved_distance)

    @property
    def adapts(self) -> bool:
        """The two observations differ (else the policy reads the scenario's as it is)."""
        return self.source != self.target

    def translate(self, obs: np.ndarray) -> np.ndarray:
        """Observations of this scenario [N, its dim] as the policy's own [N, its dim]."""
        src, dst = self.source, self.target
        n = obs.shape[0]
        out = np.zeros((n, dst.dim), dtype=np.float32)
        evaders = obs[:, : 3 * src.n_evaders].reshape(n, src.n_evaders, 3)
        out_e = out[:, : 3 * dst.n_evaders].reshape(n, dst.n_evaders, 3)
        if dst.n_evaders >= src.n_evaders:
            out_e[:, : src.n_evaders] = evaders
            out_e[:, src.n_evaders :, 0] = self.far
        else:
            pick = _nearest(evaders[:, :, 0], dst.n_evaders)
            out_e[:] = np.take_along_axis(evaders, pick[:, :, None], axis=1)
        out[:, dst.obstacle : dst.obstacle + 2] = obs[:, src.obstacle : src.obstacle + 2]
        have, room = src.n_pursuers - 1, dst.n_pursuers - 1
        mates = obs[:, src.teammates : src.own].reshape(n, have, 2)
        out_m = out[:, dst.teammates : dst.own].reshape(n, room, 2)
        if room >= have:
            pick = np.broadcast_to(np.arange(have), (n, have))
            out_m[:, :have] = mates
            out_m[:, have:, 0] = self.far
        else:
            pick = _nearest(mates[:, :, 0], room)
            out_m[:] = np.take_along_axis(mates, pick[:, :, None], axis=1)
        out[:, dst.own : dst.own + 4] = obs[:, src.own : src.own + 4]
        if dst.headings:  # the chosen teammates' headings; a padded one's reads 0
            headings = obs[:, src.base_dim : src.dim]
            out[:, dst.base_dim : dst.base_dim + pick.shape[1]] = np.take_along_axis(
                headings, pick, axis=1
            )
        return out

    def act(self, obs: np.ndarray) -> np.ndarray:
        obs = self._check(obs)
        return self.policy.act(self.translate(obs) if self.adapts else obs)

    def reset(self, mask: np.ndarray | None = None) -> None:
        self.policy.reset(mask)

    def twin(self) -> Policy:
        inner = self.policy.twin()
        if inner is self.policy:
            return self
        other = copy.copy(self)
        other.policy = inner
        return other


def fitted(config: PursuitConfig, policy: Policy) -> Policy:
    """`policy` as it plays `config`: itself where it reads `config`'s observation, else
    through a `ScenarioAdapter`."""
    if policy.config.layout == config.layout:
        return policy
    return ScenarioAdapter(config, policy)
