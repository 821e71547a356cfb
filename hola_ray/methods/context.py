"""What a method's hooks are given of the run they serve (`Context`), in place of the
trainer itself: a method reads its run through this and nothing else."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from hola_ray.methods.config import RunConfig
from hola_ray.methods.generation_zero import GenerationZero
from hola_ray.population.rundir import RunDir


@dataclass(frozen=True)
class Context:
    """What a method's hooks may use of the run they serve: its config, its folder, where
    generation 0 comes from, how to say a line, and (for a method that seats its own
    members, PBT) the coordinator and the members' weights. Built by the trainer."""

    config: RunConfig
    run: RunDir
    zero: GenerationZero | None
    say: Callable[[str], None]
    progress: bool
    coord: Any = None
    """the population's coordinator (a Ray actor handle), once started"""
    member_states: Callable[[list[int]], dict[int, dict[str, Any]]] | None = None
    """population node ids → their RLlib module states"""
