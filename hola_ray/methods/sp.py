"""Self-play: one trained module in every seat, no population (the `sp` baseline)."""

from __future__ import annotations

from typing import ClassVar

from hola_ray.methods.base import Method, Origin


class SelfPlay(Method):
    origin: ClassVar[Origin] = Origin(kind=None)

    def trains_alone(self) -> bool:
        return True

    def may_join(self) -> bool:
        return False


SP = SelfPlay("sp", "self-play: one trained module in every seat")
