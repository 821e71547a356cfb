"""Self-play: one trained module in every seat, no population (the `sp` baseline)."""

from __future__ import annotations

from typing import ClassVar

from hola_ray.methods.base import Method


class SelfPlay(Method):
    self_play: ClassVar[bool] = True
    joins: ClassVar[bool] = False
    population_kind: ClassVar[str | None] = None


SP = SelfPlay("sp", "self-play: one trained module in every seat")
