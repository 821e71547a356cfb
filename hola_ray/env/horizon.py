"""The horizon truncates an episode; it does not terminate it.

RLlib's `MultiAgentEpisode.add_env_step` declares an episode terminated once every agent is
done, however each one ended, and marks every agent of it terminated: at the horizon (every
live pursuer truncated) nothing would then bootstrap V(s_T) or Q(s_T, ·), and value targets
near the horizon are biased toward zero. `horizon_is_truncation` undoes that on a finished
episode from RLlib's own env runner: an agent whose last step the env reported truncated and
not terminated (`PursuitEnv` puts `terminated` in every agent's final info) is truncated
only, and so is an episode cut at the horizon. A pursuer that collided stays terminated.
"""

from __future__ import annotations

from typing import Any


def horizon_is_truncation(episode: Any) -> None:
    """Fix the flags of a finished RLlib `MultiAgentEpisode` in place (see the module doc)."""
    if not episode.is_truncated:
        return
    episode.is_terminated = False
    for sa in episode.agent_episodes.values():
        if not sa.is_truncated:
            continue
        infos = sa.get_infos(-1) if len(sa) else {}
        if not (infos or {}).get("terminated", False):
            sa.is_terminated = False
