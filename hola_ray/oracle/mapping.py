"""Who plays which pursuer slot in an Oracle episode: the learner and φ-sampled partners."""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence

import numpy as np

LEARNER = "learner"
"""The module id of the policy the Oracle trains."""


def member_module(slot: int) -> str:
    """The RLlib module id of population slot `slot` (a frozen partner, or an MEP member)."""
    return f"member_{slot}"


def slot_of_agent(agent_id: str) -> int:
    """The pursuer slot of a PettingZoo agent id `pursuer_<slot>`."""
    return int(str(agent_id).rsplit("_", 1)[1])


class PartnerMapping:
    """A stateful `policy_mapping_fn`: per episode, the learner takes a uniformly random slot
    (when there is a learner; `learner_seats` fixes its slots, as a team that changes within
    the episode does: the seats that never leave) and every other slot a module drawn from
    φ; or, with
    `whole_team`, one module drawn from φ plays every slot of the episode (MEP's members,
    each in self-play).

    All draws of one episode come from a generator seeded by the episode id and `salt`, so
    the call for each agent of an episode sees the same assignment. φ changes between
    generations through `set_phi`, pushed into every env runner by the Oracle.
    """

    def __init__(
        self,
        n_pursuers: int,
        phi: Mapping[str, float],
        learner: bool,
        salt: int = 0,
        whole_team: bool = False,
        learner_seats: Sequence[int] | None = None,
    ):
        if learner and whole_team:
            raise ValueError("a whole team of one module leaves no seat for the learner")
        self.n_pursuers = n_pursuers
        self.learner = learner
        self.learner_seats = tuple(learner_seats) if learner_seats is not None else None
        """the learner's slots in every episode; None: one uniformly random slot"""
        self.whole_team = whole_team
        self.salt = salt
        self.set_phi(phi)

    def set_phi(self, phi: Mapping[str, float], salt: int | None = None) -> None:
        """Partner distribution: module id → probability (normalised here)."""
        modules = list(phi)
        probs = np.array([phi[m] for m in modules], dtype=np.float64)
        if not modules or not np.all(np.isfinite(probs)) or probs.min() < 0 or probs.sum() <= 0:
            raise ValueError(f"φ must be non-negative with a positive sum, got {dict(phi)}")
        self.modules: Sequence[str] = modules
        self.probs = probs / probs.sum()
        if salt is not None:
            self.salt = salt

    @property
    def phi(self) -> dict[str, float]:
        return dict(zip(self.modules, self.probs.tolist(), strict=True))

    def assignment(self, episode_id: str) -> list[str]:
        """The module of every pursuer slot in the episode `episode_id`."""
        digest = hashlib.blake2b(f"{episode_id}/{self.salt}".encode(), digest_size=8).digest()
        rng = np.random.default_rng(int.from_bytes(digest, "little"))
        picks = rng.choice(
            len(self.modules), size=1 if self.whole_team else self.n_pursuers, p=self.probs
        )
        if self.whole_team:
            picks = np.repeat(picks, self.n_pursuers)
        out = [self.modules[k] for k in picks]
        if self.learner:
            seat = int(rng.integers(self.n_pursuers))  # drawn either way: the same stream
            for s in (seat,) if self.learner_seats is None else self.learner_seats:
                out[s] = LEARNER
        return out

    def __call__(self, agent_id: str, episode, **kwargs) -> str:
        return self.assignment(episode.id_)[slot_of_agent(agent_id)]
