"""A Crazyflie 2.x: its physical model and the Crazyflie firmware's PID cascade.

The model (mass, inertia, arm, thrust and torque coefficients, the PWM → RPM map) is the
Crazyflie 2.x as identified by Förster (2015) and used by gym-pybullet-drones' `cf2x`; the
rigid body is simulated by pybullet (`hola_ray.flight.world`). The controller is the
structure and the default gains of the firmware's `controller_pid` in velocity mode:

- position PID on z only (the height is held), giving a vertical velocity set-point;
- velocity PIDs (100 Hz): x and y in the yaw frame → pitch and roll set-points in degrees
  (at most `RP_LIMIT_DEG`); z → thrust around `THRUST_BASE`;
- attitude PIDs (500 Hz) → body-rate set-points in deg/s; rate PIDs (500 Hz) → the roll,
  pitch and yaw commands the motor mixer adds to the thrust (PWM units, the X mixer's
  halves on roll and pitch).

Signs follow one right-handed frame (x right, y up, z out of the arena's plane; roll
about body x, pitch about body y, yaw about z), not the firmware's legacy pitch sign. Every
loop runs on arrays of drones at once. State estimation is perfect (the true state).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

GRAVITY = 9.81
"""m/s²"""


@dataclass(frozen=True)
class CrazyflieModel:
    """The Crazyflie 2.x in X configuration."""

    mass: float = 0.027
    """kg"""
    inertia: tuple[float, float, float] = (1.4e-5, 1.4e-5, 2.17e-5)
    """kg·m², about body x, y, z"""
    arm: float = 0.0397
    """m, from the centre to each motor"""
    kf: float = 3.16e-10
    """N per RPM²: a motor's thrust"""
    km: float = 7.94e-12
    """N·m per RPM²: a motor's drag torque about z"""
    pwm_to_rpm: tuple[float, float] = (0.2685, 4070.3)
    """RPM = scale · PWM + offset"""
    pwm_range: tuple[float, float] = (20000.0, 65535.0)
    """the motors' PWM limits"""
    spin_up: float = 7.3556
    """1/s: a rotor's speed rises as dω/dt = spin_up · (ω_cmd − ω)"""
    spin_down: float = 2.4444e-4
    """1/(RPM·s): and falls as dω/dt = spin_down · (ω_cmd² − ω²) (crazyflow's rotor model
    identified on a cf2x; the motors' lag is what makes the firmware's stiff rate loop
    stable)"""

    @property
    def hover_pwm(self) -> float:
        return (self.hover_rpm - self.pwm_to_rpm[1]) / self.pwm_to_rpm[0]

    @property
    def hover_rpm(self) -> float:
        return math.sqrt(self.mass * GRAVITY / (4.0 * self.kf))

    def rpm(self, pwm: np.ndarray) -> np.ndarray:
        """[M, 4] PWM → the rotor speeds it commands [M, 4] (RPM)."""
        lo, hi = self.pwm_range
        return self.pwm_to_rpm[0] * np.clip(pwm, lo, hi) + self.pwm_to_rpm[1]

    def spin(self, rpm: np.ndarray, command: np.ndarray, dt: float) -> np.ndarray:
        """The rotor speeds after `dt` of chasing `command` (the asymmetric first-order
        model: linear on the way up, quadratic on the way down)."""
        up = self.spin_up * (command - rpm)
        down = self.spin_down * (command * command - rpm * rpm)
        new = rpm + dt * np.where(command >= rpm, up, down)
        return np.where(command >= rpm, np.minimum(new, command), np.maximum(new, command))

    def forces(self, rpm: np.ndarray) -> np.ndarray:
        """[M, 4] RPM → [M, 4] thrust in N."""
        return self.kf * rpm * rpm

    def wrench(self, forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """[M, 4] motor thrusts (M1 front right, M2 back right, M3 back left, M4 front
        left) → (thrust along body z [M], body torques [M, 3])."""
        d = self.arm / math.sqrt(2.0)
        f1, f2, f3, f4 = forces.T
        torque = np.stack(
            [
                d * (-f1 - f2 + f3 + f4),  # the left motors lift: roll about +x
                d * (-f1 + f2 + f3 - f4),  # the back motors lift: pitch about +y
                (self.km / self.kf) * (-f1 + f2 - f3 + f4),  # the motors' drag torques
            ],
            axis=1,
        )
        return forces.sum(axis=1), torque


# The mixer: a command's share on each motor (M1…M4), the firmware's r/2, p/2, y.
MIX_ROLL = np.array([-0.5, -0.5, 0.5, 0.5])
MIX_PITCH = np.array([-0.5, 0.5, 0.5, -0.5])
MIX_YAW = np.array([-1.0, 1.0, -1.0, 1.0])

RP_LIMIT_DEG = 20.0
"""the velocity loop's roll and pitch set-points are at most this"""
THRUST_BASE, THRUST_SCALE, THRUST_MIN = 36000.0, 1000.0, 20000.0
"""the velocity loop's thrust: base + scale · PID(vz)"""
Z_VEL_MAX = 1.0
"""m/s: the height loop's vertical velocity set-point is at most this"""
INT16 = 32767.0


@dataclass(frozen=True)
class Gains:
    """The firmware's default PID gains (kp, ki, kd)."""

    z: tuple[float, float, float] = (2.0, 0.5, 0.0)
    vxy: tuple[float, float, float] = (25.0, 1.0, 0.0)
    vz: tuple[float, float, float] = (25.0, 15.0, 0.0)
    attitude_rp: tuple[float, float, float] = (6.0, 3.0, 0.0)
    attitude_yaw: tuple[float, float, float] = (6.0, 1.0, 0.0)
    rate_rp: tuple[float, float, float] = (250.0, 500.0, 2.5)
    rate_yaw: tuple[float, float, float] = (120.0, 16.7, 0.0)


class PIDCascade:
    """The firmware's PID cascade for M drones tracking horizontal velocity set-points at
    a fixed height and yaw 0."""

    def __init__(self, drones: int, model: CrazyflieModel, gains: Gains | None = None) -> None:
        self.model, self.gains, self.m = model, gains or Gains(), drones
        gains = self.gains
        self.int_z = np.zeros(drones)
        self.int_v = np.zeros((drones, 3))
        self.int_att = np.zeros((drones, 3))
        self.int_rate = np.zeros((drones, 3))
        self.prev_rate_err = np.zeros((drones, 3))
        self.attitude_sp = np.zeros((drones, 3))  # degrees
        self.thrust = np.full(drones, model.hover_pwm)
        # start trimmed: the vz integrator holds what hovering takes above the base
        self.int_v[:, 2] = (model.hover_pwm - THRUST_BASE) / THRUST_SCALE / gains.vz[1]

    def velocity_loop(
        self,
        dt: float,
        pos: np.ndarray,
        vel: np.ndarray,
        yaw: np.ndarray,
        v_sp: np.ndarray,
        height: float,
    ) -> None:
        """100 Hz: velocity set-points [M, 2] (world x, y) and the height → attitude
        set-points and thrust."""
        g = self.gains
        ez = height - pos[:, 2]
        self.int_z += ez * dt
        vz_sp = np.clip(g.z[0] * ez + g.z[1] * self.int_z, -Z_VEL_MAX, Z_VEL_MAX)
        c, s = np.cos(yaw), np.sin(yaw)
        # the errors in the yaw frame (body x forward, body y left)
        ex = (v_sp[:, 0] - vel[:, 0]) * c + (v_sp[:, 1] - vel[:, 1]) * s
        ey = -(v_sp[:, 0] - vel[:, 0]) * s + (v_sp[:, 1] - vel[:, 1]) * c
        e = np.stack([ex, ey, vz_sp - vel[:, 2]], axis=1)
        self.int_v += e * dt
        pitch = np.clip(
            g.vxy[0] * e[:, 0] + g.vxy[1] * self.int_v[:, 0], -RP_LIMIT_DEG, RP_LIMIT_DEG
        )
        roll = -np.clip(
            g.vxy[0] * e[:, 1] + g.vxy[1] * self.int_v[:, 1], -RP_LIMIT_DEG, RP_LIMIT_DEG
        )
        self.attitude_sp = np.stack([roll, pitch, np.zeros(self.m)], axis=1)
        raw = g.vz[0] * e[:, 2] + g.vz[1] * self.int_v[:, 2]
        self.thrust = np.clip(raw * THRUST_SCALE + THRUST_BASE, THRUST_MIN, self.model.pwm_range[1])

    def attitude_loop(self, dt: float, rpy: np.ndarray, rates: np.ndarray) -> np.ndarray:
        """500 Hz: attitude [M, 3] (rad) and body rates [M, 3] (rad/s) → motor PWM [M, 4]."""
        g = self.gains
        att_err = self.attitude_sp - np.degrees(rpy)
        att_err[:, 2] = (att_err[:, 2] + 180.0) % 360.0 - 180.0
        self.int_att += att_err * dt
        kp = np.array([g.attitude_rp[0], g.attitude_rp[0], g.attitude_yaw[0]])
        ki = np.array([g.attitude_rp[1], g.attitude_rp[1], g.attitude_yaw[1]])
        rate_sp = kp * att_err + ki * self.int_att
        rate_err = rate_sp - np.degrees(rates)
        self.int_rate += rate_err * dt
        kp = np.array([g.rate_rp[0], g.rate_rp[0], g.rate_yaw[0]])
        ki = np.array([g.rate_rp[1], g.rate_rp[1], g.rate_yaw[1]])
        kd = np.array([g.rate_rp[2], g.rate_rp[2], g.rate_yaw[2]])
        out = kp * rate_err + ki * self.int_rate + kd * (rate_err - self.prev_rate_err) / dt
        self.prev_rate_err = rate_err
        out = np.clip(out, -INT16, INT16)
        return (
            self.thrust[:, None]
            + out[:, 0:1] * MIX_ROLL
            + out[:, 1:2] * MIX_PITCH
            + out[:, 2:3] * MIX_YAW
        )
