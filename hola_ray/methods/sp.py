"""Self-play: one trained module in every seat, no population (the `sp` baseline)."""

from __future__ import annotations

from typing import ClassVar

from hola_ray.methods.base import Method, Origin


class SelfPlay(Method):
    self_play: ClassVar[bool] = True
    joins: ClassVar[bool] = False
    origin: ClassVar[Origin] = Origin(kind=None)


SP = SelfPlay("sp", "self-play: one trained module in every seat")
