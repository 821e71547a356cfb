"""The arena's kernel data: the scenario's constants packed for the kernels (`Params`,
indexed by the `F_*` and `I_*` constants, filled by `pack_params`), the per-episode state
(`Arena`), a step's outputs (`StepOut`), and the geometry every kernel shares."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from hola_ray.config.scenario import PursuitConfig
from hola_ray.env.geometry import norm

F_WIDTH = 0
F_HEIGHT = 1
F_DT = 2
F_V_P = 3
F_V_E = 4
F_MAX_TURN = 5
F_CAPTURE = 6
F_PERCEPTION = 7
F_SAFE = 8
F_KAPPA = 9
F_OBS_SCALE = 10
F_UNOBSERVED = 11
F_CAPTURE_REWARD = 12
F_COLLISION_PENALTY = 13
F_APPROACH_SCALE = 14
F_E_SENS = 15
F_E_PANIC = 16
F_E_WANDER_CLEAR = 17
F_E_REP_GAIN = 18
F_E_REP_RANGE = 19
F_E_REP_OFFSET = 20
F_E_SWITCH = 21
F_E_PUSH = 22
F_E_SLIP_RANGE = 23
F_E_SLIP_START = 24
F_E_SLIP_KEEP = 25
F_E_MAX_TURN = 26
F_E_MIN_CLEAR = 27
F_SPAWN_SEP = 28
F_OBSTACLE_PENALTY = 29
F_OBSTACLE_REACH = 30
F_MATE_PENALTY = 31
F_MATE_REACH = 32
F_APPROACH_OWN = 33
F_RESPONSE = 34
F_SHARED = 35
F_MATE_GRADED = 36
F_TEAM_FROM = 37
F_TEAM_TO = 38
N_FLOAT_PARAMS = 39

# ---- packed integer parameters ------------------------------------------------------
I_HORIZON = 0
I_HOLD_MIN = 1
I_HOLD_MAX = 2
I_RESPONSE_DELAY = 3
I_HEADINGS = 4
I_OBS_PURSUERS = 5
I_OBS_EVADERS = 6
I_TEAM_PRESENT = 7
I_TEAM_CHANGES = 8
I_TEAM_MIN = 9
I_TEAM_FIXED = 10
I_TEAM_PRESENT_HIGH = 11
I_ARENAS = 12
N_INT_PARAMS = 13

_NOWHERE = -1.0e6
"""Where a layout with fewer shapes than another keeps its spare ones: a point box or disc
so far outside the arena that no wall is farther, so nothing sees, hits or is repelled by
it."""


class Params(NamedTuple):
    """Constants of the scenario, packed for the kernels."""

    fp: np.ndarray  # [N_FLOAT_PARAMS] float64, indexed by F_*
    ip: np.ndarray  # [N_INT_PARAMS] int64, indexed by I_*
    rects: np.ndarray  # [A, K, 4] each layout's boxes as (x_min, y_min, x_max, y_max)
    spawn: np.ndarray  # [2, 4] pursuer then evader spawn region (x0, x1, y0, y1)
    discs: np.ndarray  # [A, K, 3] each layout's discs as (centre_x, centre_y, radius)


class Arena(NamedTuple):
    """Per-episode state of a batch of B episodes (n_p pursuers, n_e evaders)."""

    ppos: np.ndarray  # [B, n_p, 2] pursuer positions
    phead: np.ndarray  # [B, n_p] pursuer headings
    pactive: np.ndarray  # [B, n_p] bool, not disabled
    epos: np.ndarray  # [B, n_e, 2] evader positions
    ehead: np.ndarray  # [B, n_e] evader headings
    ealive: np.ndarray  # [B, n_e] bool, not captured
    wander_left: np.ndarray  # [B, n_e] int64, steps the wander heading is still held
    wander_dir: np.ndarray  # [B, n_e] the wander heading
    slip: np.ndarray  # [B, n_e] bool, slipping between two pursuers
    slip_dir: np.ndarray  # [B, n_e, 2] direction of the slip when it started
    t: np.ndarray  # [B] int64 steps taken
    done: np.ndarray  # [B] bool, episode over
    collided: np.ndarray  # [B] bool, a collision happened
    captures: np.ndarray  # [B] int64 evaders captured
    ep_return: np.ndarray  # [B, n_p] summed rewards
    rng: np.ndarray  # [B] uint64 SplitMix64 stream states
    pvel: np.ndarray  # [B, n_p, 2] pursuer velocities (the response model; else unused)
    pcmd: np.ndarray  # [B, n_p, 2] the velocity commanded a step ago (response delay 1)
    ppresent: np.ndarray  # [B, n_p] bool, in play (not landed, not waiting to join)
    pwaiting: np.ndarray  # [B, n_p] bool, not yet in play: may join
    change_t: np.ndarray  # [B, K] int64, the steps of the team's changes (K ≥ 1)
    team_rng: np.ndarray  # [B, K + 1] uint64, the team's streams: its start, each change
    layout: np.ndarray  # [B] int64, the episode's layout: an index of Params.rects


class StepOut(NamedTuple):
    """What a step writes, plus scratch space."""

    obs: np.ndarray  # [B, n_p, obs_dim] float32
    reward: np.ndarray  # [B, n_p]
    terminated: np.ndarray  # [B] bool
    truncated: np.ndarray  # [B] bool
    disabled: np.ndarray  # [B, n_p] bool, collided this step
    new_heading: np.ndarray  # [B, n_e] scratch: evader decisions
    dist_prev: np.ndarray  # [B, n_p, n_e] scratch: distances before the move


def pack_params(config: PursuitConfig) -> Params:
    """The scenario's constants in kernel form."""
    ev = config.evader
    fp = np.zeros(N_FLOAT_PARAMS, dtype=np.float64)
    fp[F_WIDTH] = config.arena_width
    fp[F_HEIGHT] = config.arena_height
    fp[F_DT] = config.dt
    fp[F_V_P] = config.pursuer_speed
    fp[F_V_E] = config.evader_speed
    fp[F_MAX_TURN] = config.max_turn
    fp[F_CAPTURE] = config.capture_distance
    fp[F_PERCEPTION] = config.perception_range
    fp[F_SAFE] = config.safe_radius
    fp[F_KAPPA] = config.pursuer_collision_distance
    fp[F_OBS_SCALE] = config.obs_distance_scale
    fp[F_UNOBSERVED] = config.unobserved_distance
    reward = config.reward
    fp[F_CAPTURE_REWARD] = reward.capture
    fp[F_COLLISION_PENALTY] = reward.collision
    fp[F_APPROACH_SCALE] = reward.approach_scale
    fp[F_OBSTACLE_PENALTY] = reward.obstacle_penalty
    fp[F_OBSTACLE_REACH] = reward.obstacle_distance
    fp[F_MATE_PENALTY] = reward.teammate_penalty
    fp[F_MATE_REACH] = reward.teammate_distance
    fp[F_APPROACH_OWN] = float(reward.approach == "own_move")
    fp[F_SHARED] = float(reward.shared)
    fp[F_MATE_GRADED] = float(reward.teammate_graded)
    fp[F_E_SENS] = ev.sensitivity_range
    fp[F_E_PANIC] = ev.panic_threshold
    fp[F_E_WANDER_CLEAR] = ev.wander_clearance
    fp[F_E_REP_GAIN] = ev.repulsion_gain
    fp[F_E_REP_RANGE] = ev.repulsion_range
    fp[F_E_REP_OFFSET] = ev.repulsion_offset
    fp[F_E_SWITCH] = ev.wall_follow_switch_distance
    fp[F_E_PUSH] = ev.wall_follow_push_distance
    fp[F_E_SLIP_RANGE] = ev.slip_range
    fp[F_E_SLIP_START] = ev.slip_start_clearance
    fp[F_E_SLIP_KEEP] = ev.slip_keep_clearance
    fp[F_E_MAX_TURN] = ev.max_turn
    fp[F_E_MIN_CLEAR] = ev.min_clearance
    fp[F_SPAWN_SEP] = config.spawn_separation
    fp[F_RESPONSE] = config.pursuer_response
    fp[F_TEAM_FROM], fp[F_TEAM_TO] = config.team.window
    ip = np.array(
        [
            config.horizon,
            ev.wander_hold_min,
            ev.wander_hold_max,
            config.pursuer_response_delay,
            int(config.observe_headings),
            config.pursuer_slots,
            config.evader_slots,
            config.team.start_range(config.n_pursuers)[0],
            config.team.changes,
            config.team.min_team,
            config.team.fixed,
            config.team.start_range(config.n_pursuers)[1],
            len(config.arenas),
        ],
        dtype=np.int64,
    )
    layouts = config.layouts
    rects = np.full((len(layouts), max(len(b) for b, _ in layouts), 4), _NOWHERE)
    discs = np.full((len(layouts), max(len(d) for _, d in layouts), 3), _NOWHERE)
    discs[..., 2] = 0.0
    for a, (boxes, round_ones) in enumerate(layouts):
        for k, (cx, cy, w, h) in enumerate(boxes):
            rects[a, k] = (cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2)
        for k, disc in enumerate(round_ones):
            discs[a, k] = disc
    spawn = np.array([config.pursuer_spawn, config.evader_spawn], dtype=np.float64)
    return Params(fp, ip, rects, spawn, discs)


@njit(cache=True, inline="always")
def statics(b, p, s):
    """Episode b's boxes and discs: its layout's rows of `Params.rects` and `.discs`."""
    return p.rects[s.layout[b]], p.discs[s.layout[b]]


# ---- geometry -------------------------------------------------------------------------
@njit(cache=True, inline="always")
def nearest_on_disc(px, py, cx, cy, r):
    """Nearest point (qx, qy) of a disc's rim to (px, py), and its distance (0 inside)."""
    dx, dy = px - cx, py - cy
    dc = norm(dx, dy)
    if dc <= 0.0:
        return cx + r, cy, 0.0
    return cx + r * dx / dc, cy + r * dy / dc, max(dc - r, 0.0)


@njit(cache=True)
def nearest_static(px, py, rects, discs, width, height):
    """Nearest point (qx, qy) on the walls, any box or any disc to (px, py), and its
    distance."""
    qx, qy, best = 0.0, py, px  # left wall
    if width - px < best:
        qx, qy, best = width, py, width - px
    if py < best:
        qx, qy, best = px, 0.0, py
    if height - py < best:
        qx, qy, best = px, height, height - py
    for k in range(rects.shape[0]):
        cx = min(max(px, rects[k, 0]), rects[k, 2])
        cy = min(max(py, rects[k, 1]), rects[k, 3])
        d = norm(px - cx, py - cy)
        if d < best:
            qx, qy, best = cx, cy, d
    for k in range(discs.shape[0]):
        cx, cy, d = nearest_on_disc(px, py, discs[k, 0], discs[k, 1], discs[k, 2])
        if d < best:
            qx, qy, best = cx, cy, d
    return qx, qy, best
