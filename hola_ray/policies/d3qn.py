"""D3QN-G: a dueling double DQN that picks APF-A's (λ, η) pair, then Greedy (docs/contract.md §3).

As in DACOOP-A (Zhang et al., RA-L 2023; Zero8319/DACOOP-A, `Codes/attention3.py` and
`Codes/environment.py`), each pursuer's DQN reads a small state and its discrete action
picks one of the 24 APF-A pairs (`hola_ray.policies.apf`), toward the first evader; once
that evader is captured the pursuer plays Greedy. The state (`dacoop_state`), all read
from the project's observation, in its units (distance / 5, bearing / π):

    [nearest obstacle d, bearing; first evader d, bearing; bit; each teammate d, bearing]

DACOOP-A's bit says that some pursuer is inactive; the observation cannot tell a disabled
teammate from one out of perception range (both read (2, 0)), so here the bit is set when
any teammate reads (2, 0). Teammates beyond d_p read (2, 0) in both.

Training (`train_d3qn`): RLlib's DQN on the new API stack, one module shared by every
pursuer (DACOOP-A's one network for all three), dueling, double Q, prioritised episode
replay, ε-greedy; the arena's own rewards; three pursuers against one evader, DACOOP-A's
scenario. DACOOP-A's own budget (4,000 episodes after a full 10⁶-transition memory, 1,000
updates per episode, lr 3e-5) is far beyond two CPUs; the config file says what is used
instead. The export is a plain dict played by `D3QNG` without RLlib.
"""

from __future__ import annotations

import copy
from collections.abc import Mapping
from typing import Any

import numpy as np
import torch

from hola_ray.config.layout import ObsLayout
from hola_ray.config.scenario import PursuitConfig
from hola_ray.policies.apf import APFConfig, apf_actions
from hola_ray.policies.base import Policy
from hola_ray.policies.greedy import Greedy

FORMAT = "hola_ray.d3qn/1"
"""The version tag of a D3QN-G export."""


def dacoop_state(obs: np.ndarray, layout: ObsLayout, far: float) -> np.ndarray:
    """Observations [N, D] → DACOOP-A states [N, 5 + 2·(n_p − 1)] (see the module doc)."""
    mates = obs[:, layout.teammates : layout.own]
    unseen = (mates[:, 0::2] >= far).any(axis=1, keepdims=True)
    return np.concatenate(
        [
            obs[:, layout.obstacle : layout.obstacle + 2],
            obs[:, layout.evaders : layout.evaders + 2],
            unseen.astype(np.float32),
            mates,
        ],
        axis=1,
    ).astype(np.float32)


def state_dim(config: PursuitConfig) -> int:
    """The DACOOP-A state's size in `config`'s observation (its teammate slots)."""
    return 5 + 2 * (config.pursuer_slots - 1)


def state_pursuers(export: Mapping[str, Any]) -> int:
    """The team a D3QN-G export was trained in: the pursuers its state holds."""
    return (int(export["state_dim"]) - 5) // 2 + 1


class PairActor:
    """APF-A with a (λ, η) pair per row toward the first evader, Greedy once it is caught."""

    def __init__(self, config: PursuitConfig, params: APFConfig | None = None) -> None:
        self.config = config
        self.params = params or APFConfig()
        pairs = np.array(self.params.pairs)
        self.lam, self.eta = pairs[:, 0], pairs[:, 1]
        self.greedy = Greedy(config)
        self.far = config.unobserved_distance

    def act(self, obs: np.ndarray, pair: np.ndarray) -> np.ndarray:
        pair = np.asarray(pair, dtype=np.int64)
        out = np.asarray(
            apf_actions(
                self.config,
                self.params,
                obs,
                self.lam[pair],
                self.eta[pair],
                np.zeros(obs.shape[0], dtype=np.int64),
            ),
            dtype=np.float64,
        )
        caught = obs[:, 0] >= self.far  # the first evader's distance reads 2: captured
        if caught.any():
            out[caught] = self.greedy.act(obs[caught])
        return out


class DuelingQ(torch.nn.Module):
    """Q(s, ·) = V(s) + A(s, ·) − mean A(s, ·) over a shared tanh/relu MLP trunk."""

    def __init__(self, export: Mapping[str, Any]) -> None:
        super().__init__()
        self.trunk = [(torch.as_tensor(w), torch.as_tensor(b)) for w, b in export["trunk"]]
        self.advantage = [(torch.as_tensor(w), torch.as_tensor(b)) for w, b in export["advantage"]]
        self.value = [(torch.as_tensor(w), torch.as_tensor(b)) for w, b in export["value"]]
        self.activation = {"relu": torch.relu, "tanh": torch.tanh}[export["activation"]]

    def _mlp(self, x, layers, last_linear: bool):
        for k, (w, b) in enumerate(layers):
            x = torch.nn.functional.linear(x, w, b)
            if k < len(layers) - 1 or not last_linear:
                x = self.activation(x)
        return x

    @torch.no_grad()
    def forward(self, state: torch.Tensor) -> torch.Tensor:
        h = self._mlp(state, self.trunk, last_linear=False)
        a = self._mlp(h, self.advantage, last_linear=True)
        v = self._mlp(h, self.value, last_linear=True)
        return v + a - a.mean(dim=-1, keepdim=True)


class D3QNG(Policy):
    """A trained D3QN-G from its export: the greedy pair of its Q-network, played by APF-A."""

    def __init__(self, config: PursuitConfig, export: Mapping[str, Any], name: str = "D3QN-G"):
        super().__init__(config)
        if export.get("format") != FORMAT:
            raise ValueError(f"not a {FORMAT} export (format {export.get('format')!r})")
        if int(export["state_dim"]) != state_dim(config):
            raise ValueError(
                f"{name} reads {export['state_dim']}-dim states; this scenario gives "
                f"{state_dim(config)}"
            )
        self.name = name
        self.q = DuelingQ(export)
        self.actor = PairActor(config)
        self.interval = int(export.get("decision_interval", 1))
        self._pair = np.zeros(0, dtype=np.int64)
        self._age = np.zeros(0, dtype=np.int64)

    def pairs(self, obs: np.ndarray) -> np.ndarray:
        """The Q-network's greedy pair for each observation row."""
        state = dacoop_state(obs, self.layout, self.config.unobserved_distance)
        return self.q(torch.from_numpy(state)).argmax(dim=-1).numpy()

    def twin(self) -> D3QNG:
        """The same network and pair actor, with pairs and ages of its own."""
        other = copy.copy(self)
        other._pair = np.zeros(0, dtype=np.int64)
        other._age = np.zeros(0, dtype=np.int64)
        return other

    def reset(self, mask: np.ndarray | None = None) -> None:
        """Rows in mask pick a fresh pair at their next step (binds len(mask) rows)."""
        if mask is None:
            self._age[:] = 0
            return
        mask = np.asarray(mask, dtype=bool)
        if len(mask) != len(self._age):
            self._pair = np.zeros(len(mask), dtype=np.int64)
            self._age = np.zeros(len(mask), dtype=np.int64)
        self._age[mask] = 0

    def act(self, obs: np.ndarray) -> np.ndarray:
        """APF-A with each row's pair, re-picked every `decision_interval` steps."""
        obs = self._check(obs)
        if len(obs) != len(self._age):
            self.reset(np.ones(len(obs), dtype=bool))
        due = self._age % self.interval == 0
        if due.any():
            self._pair[due] = self.pairs(obs[due])
        self._age += 1
        return self.actor.act(obs, self._pair)
