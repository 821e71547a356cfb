"""Crazyflies in pybullet: rigid bodies with the Crazyflie's mass and inertia, driven by
their four motors' thrusts and drag torques, each flown by the firmware's PID cascade.

pybullet integrates the bodies (`PHYSICS_HZ`); the attitude and rate loops run every
physics step, the velocity and height loops every fifth (the firmware's 500 Hz / 100 Hz).
The bodies have no collision shapes: contact is the arena's business (its safe radius and
κ on the true positions), so drones pass through each other in pybullet.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from hola_ray.flight.crazyflie import GRAVITY, CrazyflieModel, PIDCascade

PHYSICS_HZ = 500
"""pybullet steps per second, and the attitude loop's rate"""
VELOCITY_EVERY = 5
"""physics steps per velocity-loop step (100 Hz)"""

_URDF = """<?xml version="1.0"?>
<robot name="crazyflie2x">
  <link name="base_link">
    <inertial>
      <origin xyz="0 0 0" rpy="0 0 0"/>
      <mass value="{mass}"/>
      <inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" izz="{izz}"/>
    </inertial>
  </link>
</robot>
"""


class Quadrotors:
    """M Crazyflies in one pybullet world (DIRECT mode, no window)."""

    def __init__(self, start: np.ndarray, model: CrazyflieModel | None = None) -> None:
        """start: [M, 3] positions, hovering, yaw 0."""
        import pybullet

        self.p = pybullet
        self.model = model = model or CrazyflieModel()
        self.client = pybullet.connect(pybullet.DIRECT)
        pb, cid = pybullet, self.client
        pb.setGravity(0.0, 0.0, -GRAVITY, physicsClientId=cid)
        pb.setTimeStep(1.0 / PHYSICS_HZ, physicsClientId=cid)
        ixx, iyy, izz = model.inertia
        with tempfile.TemporaryDirectory() as tmp:
            urdf = Path(tmp) / "crazyflie2x.urdf"
            urdf.write_text(_URDF.format(mass=model.mass, ixx=ixx, iyy=iyy, izz=izz))
            self.bodies = [
                pb.loadURDF(
                    str(urdf),
                    basePosition=[float(v) for v in xyz],
                    flags=pb.URDF_USE_INERTIA_FROM_FILE,
                    physicsClientId=cid,
                )
                for xyz in np.asarray(start, dtype=float)
            ]
        for body in self.bodies:
            pb.changeDynamics(body, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=cid)
        self.m = len(self.bodies)
        self.controller = PIDCascade(self.m, model)
        self.rotors = np.full((self.m, 4), model.hover_rpm)  # spinning, hovering
        self.live = np.ones(self.m, dtype=bool)  # drones still simulated
        self.steps = 0
        m = self.m
        self.pos, self.vel = np.zeros((m, 3)), np.zeros((m, 3))
        self.rpy, self.rates = np.zeros((m, 3)), np.zeros((m, 3))
        self.rot = np.tile(np.eye(3), (m, 1, 1))
        self._read()

    def close(self) -> None:
        if self.client is not None:
            self.p.disconnect(physicsClientId=self.client)
            self.client = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - the interpreter may be shutting down
            pass

    def _read(self) -> None:
        """The live drones' state from pybullet into pos, vel, rot, rpy and body rates."""
        pb, cid = self.p, self.client
        for k in np.flatnonzero(self.live):
            body = self.bodies[k]
            pos, quat = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
            vel, omega = pb.getBaseVelocity(body, physicsClientId=cid)
            rot = np.asarray(pb.getMatrixFromQuaternion(quat)).reshape(3, 3)
            self.pos[k], self.vel[k], self.rot[k] = pos, vel, rot
            self.rpy[k] = pb.getEulerFromQuaternion(quat)
            self.rates[k] = rot.T @ np.asarray(omega)  # body rates

    def fly(self, v_sp: np.ndarray, height: float, seconds: float) -> None:
        """Track the horizontal velocity set-points [M, 2] at `height` for `seconds`."""
        pb, cid = self.p, self.client
        model, ctrl = self.model, self.controller
        dt = 1.0 / PHYSICS_HZ
        for _ in range(round(seconds * PHYSICS_HZ)):
            if self.steps % VELOCITY_EVERY == 0:
                ctrl.velocity_loop(
                    dt * VELOCITY_EVERY, self.pos, self.vel, self.rpy[:, 2], v_sp, height
                )
            pwm = ctrl.attitude_loop(dt, self.rpy, self.rates)
            self.rotors = model.spin(self.rotors, model.rpm(pwm), dt)
            thrust, torque = model.wrench(model.forces(self.rotors))
            force_w = self.rot[:, :, 2] * thrust[:, None]  # body z in the world
            torque_w = np.einsum("mij,mj->mi", self.rot, torque)
            for k in np.flatnonzero(self.live):
                body = self.bodies[k]
                pb.applyExternalForce(
                    body,
                    -1,
                    force_w[k].tolist(),
                    self.pos[k].tolist(),
                    pb.WORLD_FRAME,
                    physicsClientId=cid,
                )
                pb.applyExternalTorque(
                    body, -1, torque_w[k].tolist(), pb.WORLD_FRAME, physicsClientId=cid
                )
            pb.stepSimulation(physicsClientId=cid)
            self.steps += 1
            self._read()
