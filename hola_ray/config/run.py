"""A run's own sections: MEP pre-training (`pretrain`) and the validation teammates
(`validation`), beside the scenario's, the Oracle's and the population's in this package;
`hola_ray.methods.config.RunConfig` puts them together with the methods' own."""

from __future__ import annotations

from dataclasses import dataclass

from hola_ray.config.reader import finite_in, positive_int, require


@dataclass(frozen=True)
class PretrainConfig:
    """MEP pre-training of the initial population (paper §IV-B, pre-training phase)."""

    env_steps: int = 200_000
    """environment steps of PPO training of the initial population; with `until_success`,
    the most it may take"""
    alpha: float = 0.05
    """α: weight of the population mean policy's entropy bonus −log π̄(a|s), in [0, 1]"""
    alpha_until: int = 0
    """> 0: the population-entropy bonus applies for the first alpha_until env steps only;
    after them the members train on with α 0 (the same weights, a fresh optimizer), to
    narrow the spread the bonus keeps wide; 0: α throughout"""
    scheme: str = "self-play"
    """self-play: each member in self-play, its own copies in every seat of an episode (as
    MEP trains its population; the bonus's π̄ is over all members); mixed: the members
    drawn per seat into mixed teams (the joint scheme before it, kept for ablation)"""
    until_success: float = 0.0
    """> 0: stop once every member, as a team of its own copies, succeeds in at least this
    share of `until_episodes` episodes (and collides in at most `until_collision`),
    judged every `check_every` env steps; 0: train for `env_steps`"""
    until_collision: float = 1.0
    """the most collision of every member as a team of its own copies, with `until_success`"""
    until_episodes: int = 300
    """episodes per member at each check"""
    until_in_a_row: int = 1
    """checks in a row that must find every member competent before the build stops: the
    first check to pass is also the one its noise favoured (mep-3v2-s1 stopped when a member
    read 32 % collision on 300 episodes, then collided 39 % in its manifest's 500)"""
    check_every: int = 200_000
    """environment steps between checks"""
    population: str = "none"
    """a shipped population (pools/populations/<name>, or a folder with its manifest) taken
    as generation 0 instead of pre-training; `{seed}` in the name is the run's seed
    (`{seed%N}` modulo N) and `{kind}` the kind of population its method builds
    (`mep-3v1-s{seed}`, `{kind}-3v2-s{seed%3}`; `hola_ray.population.shipped`); none:
    pre-train. A method
    without a population (self-play) takes only its learner's start from it
    (`learner_start: member`)"""
    learner_start: str = "random"
    """the learner's weights at generation 1: random (a fresh network), or member: a copy of
    the generation-0 member the population prefers most (the highest η, preference
    centrality; the lowest node on a tie), as the paper's Oracle maps a strategy j to
    BR(j, G_j) and G_0's most preferred member is the natural j at generation 1; for
    self-play, the most preferred member of the shipped `population` (FCP's: a self-play
    checkpoint; with `population: none`, random); PBT, whose generations train its agents
    in turn, ignores it"""

    members_from: str = "none"
    """a population (a shipped one's name, or a folder holding a population manifest, kept
    below its bar included) whose members' weights pre-training starts from, node k as
    member k, instead of RLlib's initialisation: a build that trains on from another, under
    a changed reward, say (`mep-open5-s1` from `mep-open5-s0`, docs/open-teams.md). It must
    hold `population.initial_size` members observed as this run observes. Its own env
    steps are its manifest's, not this build's; none: off"""

    start_agent: str = "none"
    """a shipped population (as `population` names one) whose last node every method's
    learner starts from at generation 1, in place of `learner_start`: a neutral start, the
    same for every method of a seed and in no population a run trains beside, nor in a
    pool (checked when the run starts); for an FCP-built start, its last agent's end
    checkpoint. PBT, whose generations train its agents in turn, begins every agent as a
    copy of it (with `population: none`); none: off"""

    def validate(self) -> None:
        positive_int("pretrain", self, "env_steps", maximum=10**11)
        finite_in("pretrain", self, "alpha", 0.0, 1.0, "in [0, 1]")
        ok = isinstance(self.alpha_until, int) and not isinstance(self.alpha_until, bool)
        require(
            ok and 0 <= self.alpha_until <= 10**11,
            "pretrain.alpha_until",
            "an integer >= 0 (0: the bonus throughout)",
            self.alpha_until,
        )
        require(
            self.scheme in PRETRAIN_SCHEMES,
            "pretrain.scheme",
            " or ".join(PRETRAIN_SCHEMES),
            self.scheme,
        )
        finite_in("pretrain", self, "until_success", 0.0, 1.0, "in [0, 1] (0: off)")
        finite_in("pretrain", self, "until_collision", 0.0, 1.0, "in [0, 1]")
        positive_int("pretrain", self, "until_episodes", maximum=10**6)
        positive_int("pretrain", self, "until_in_a_row", maximum=1000)
        positive_int("pretrain", self, "check_every", maximum=10**11)
        require(
            isinstance(self.population, str) and bool(self.population),
            "pretrain.population",
            "none or a shipped population's name or folder",
            self.population,
        )
        require(
            isinstance(self.members_from, str) and bool(self.members_from),
            "pretrain.members_from",
            "none or a population's name or folder",
            self.members_from,
        )
        require(
            isinstance(self.start_agent, str) and bool(self.start_agent),
            "pretrain.start_agent",
            "none or a shipped population's name or folder",
            self.start_agent,
        )
        require(
            self.learner_start in LEARNER_STARTS,
            "pretrain.learner_start",
            " or ".join(LEARNER_STARTS),
            self.learner_start,
        )

    @property
    def shipped(self) -> bool:
        """Whether generation 0 is a shipped population."""
        return self.population != "none"

    @property
    def until(self) -> bool:
        """Whether pre-training stops at competence (else after `env_steps`)."""
        return self.until_success > 0


LEARNER_STARTS = ("random", "member")
"""`pretrain.learner_start`: the learner's weights at generation 1"""

PRETRAIN_SCHEMES = ("self-play", "mixed")
"""`pretrain.scheme`: how MEP's members share the episodes"""


EVALUATION_POOLS = ("hot", "het")
"""the zero-shot evaluation's pools: never a run's validation teammates"""


@dataclass(frozen=True)
class ValidationConfig:
    """Validation teammates (the held-out protocol of jax-aht): after every generation the
    learner plays with teammates drawn from a set disjoint from the evaluation pools, built
    only from what training may see; every method keeps as `best.pt` the generation that
    does best there (highest success, then lowest collision)."""

    pool: str = "validation"
    """the committed validation set (`pools/validation`, `python -m hola_ray pools show
    --pool validation`), a folder holding such a manifest, or none (best.pt then follows
    each method's own judging)"""
    episodes: int = 96
    """episodes per validation: the learner in a random seat, teammates drawn per episode"""

    def validate(self) -> None:
        positive_int("validation", self, "episodes", maximum=10**6)
        ok = isinstance(self.pool, str) and self.pool not in EVALUATION_POOLS and self.pool
        require(
            bool(ok),
            "validation.pool",
            "validation, none or a folder with a pool manifest; never an evaluation pool "
            f"({', '.join(EVALUATION_POOLS)})",
            self.pool,
        )

    @property
    def enabled(self) -> bool:
        return self.pool != "none"
