"""The learned team flown as Crazyflies (pybullet, the firmware's PID cascade): the
sim-to-sim check of `python -m hola_ray fly`."""

from hola_ray.flight.crazyflie import CrazyflieModel, PIDCascade
from hola_ray.flight.dynamics import HEIGHT, Crazyflies, GuardedArena
from hola_ray.flight.guard import Guard
from hola_ray.flight.world import PHYSICS_HZ, Quadrotors

__all__ = [
    "HEIGHT",
    "PHYSICS_HZ",
    "CrazyflieModel",
    "Crazyflies",
    "Guard",
    "GuardedArena",
    "PIDCascade",
    "Quadrotors",
]
