"""HOLA-Drone as configuration of one trainer: the run config and the generation loop."""

from hola_ray.methods.config import METHODS, RunConfig

__all__ = ["METHODS", "RunConfig"]
