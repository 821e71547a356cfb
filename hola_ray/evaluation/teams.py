"""A learner among drawn teammates: the zero-shot evaluation's episodes (paper §V) and the
validation teammates' (held-out protocol), one code path for both.

Per seed, every episode seats the learner in a uniformly random seat (in its fixed seats,
0 … team.fixed − 1, which never leave, when the team changes within the episode) and fills
the other seats with uniform draws (with replacement) from the teammates; a seat that waits
to join plays its draw once it joins. The draws depend on the seed only, so every learner
evaluated with the same seeds plays the same episodes.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hola_ray.config.scenario import PursuitConfig
from hola_ray.evaluation.compare import FIELDS
from hola_ray.evaluation.metrics import zero_shot_values
from hola_ray.evaluation.rollout import rollout


def draw_teams(
    rng: np.random.Generator, episodes: int, n_p: int, members: int, fixed: int = 0
) -> np.ndarray:
    """[episodes, n_p] indices into [learner, member 1 … member M]: the learner (0) in a
    uniformly random seat (`fixed` > 0: in seats 0 … fixed − 1, the seats a team that
    changes never lets go, contract §6.3), every other seat a uniform draw from the members
    (1 … M)."""
    teams = rng.integers(1, members + 1, size=(episodes, n_p))
    seats = rng.integers(0, n_p, size=episodes)  # drawn either way: the same stream
    if fixed > 0:
        teams[:, :fixed] = 0
    else:
        teams[np.arange(episodes), seats] = 0
    return teams


def partner_combinations(teams: np.ndarray, members: int) -> np.ndarray:
    """[E] an id per episode of the members beside the learner, as a multiset (seat order
    and the learner's seats left out): the bootstrap's strata."""
    own = int((teams[0] == 0).sum())
    mates = np.sort(teams[teams != 0].reshape(teams.shape[0], teams.shape[1] - own), axis=1)
    base = members + 1
    return (mates * base ** np.arange(mates.shape[1])[::-1]).sum(axis=1)


def play(
    learner, members: list, config: PursuitConfig, episodes: int, seeds: Sequence[int]
) -> dict[str, np.ndarray]:
    """Every episode's record ([episodes · seeds] per field of `FIELDS`, and `eval_seed`):
    per seed, `episodes` episodes with drawn teams."""
    out: dict[str, list[np.ndarray]] = {m: [] for m in (*FIELDS, "eval_seed")}
    n_p = config.n_pursuers
    for s in seeds:
        rng = np.random.default_rng(np.random.SeedSequence([int(s), 7]))
        fixed = len(config.team.learner_seats or ())  # 0: one random seat
        teams = draw_teams(rng, episodes, n_p, len(members), fixed)
        result = rollout(config, [learner, *members], episodes, assignment=teams, seed=int(s))
        seats = teams == 0  # the learner is candidate 0, in one seat or its fixed ones
        for name, values in zero_shot_values(result, seats, n_p).items():
            out[name].append(values)
        out["stratum"].append(partner_combinations(teams, len(members)))
        out["eval_seed"].append(np.full(episodes, int(s)))
    return {m: np.concatenate(v) for m, v in out.items()}
