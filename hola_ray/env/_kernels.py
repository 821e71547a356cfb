"""Compiled per-episode physics of the pursuit arena: one loop over the batch, numba-jitted.

Everything here is plain arrays in, arrays out, grouped in three named tuples: `Params`
(constants), `Arena` (per-episode state) and `StepOut` (per-step outputs and scratch).
`core.BatchedPursuit` owns the arrays and is the only caller. The parameter vector `fp` is
indexed by the `F_*` constants below and filled by `pack_params`; obstacles arrive as
`rects` [K, 4] = (x_min, y_min, x_max, y_max).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit, prange

from hola_ray.env import _rng
from hola_ray.env.config import PursuitConfig
from hola_ray.env.geometry import norm, wrap

# ---- packed float parameters --------------------------------------------------------
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
N_FLOAT_PARAMS = 34

# ---- packed integer parameters ------------------------------------------------------
I_HORIZON = 0
I_HOLD_MIN = 1
I_HOLD_MAX = 2
N_INT_PARAMS = 3

_E = math.e
_REP_MIN = 0.005  # floor of (d − offset) in the repulsion, so a grazing evader stays finite


class Params(NamedTuple):
    """Constants of the scenario, packed for the kernels."""

    fp: np.ndarray  # [N_FLOAT_PARAMS] float64, indexed by F_*
    ip: np.ndarray  # [N_INT_PARAMS] int64, indexed by I_*
    rects: np.ndarray  # [K, 4] bars as (x_min, y_min, x_max, y_max)
    spawn: np.ndarray  # [2, 4] pursuer then evader spawn region (x0, x1, y0, y1)


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
    ip = np.array([config.horizon, ev.wander_hold_min, ev.wander_hold_max], dtype=np.int64)
    rects = np.array(
        [(cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2) for cx, cy, w, h in config.obstacles],
        dtype=np.float64,
    ).reshape(-1, 4)
    spawn = np.array([config.pursuer_spawn, config.evader_spawn], dtype=np.float64)
    return Params(fp, ip, rects, spawn)


# ---- geometry -------------------------------------------------------------------------
@njit(cache=True)
def nearest_static(px, py, rects, width, height):
    """Nearest point (qx, qy) on the walls or any bar to (px, py), and its distance."""
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
    return qx, qy, best


@njit(cache=True, inline="always")
def _repulse(px, py, qx, qy, d, gain, reach, offset):
    """DACOOP obstacle repulsion from point q: gain·(1/(d−r) − 1/R)/(d−r)² along p − q."""
    if d >= reach or d <= 0.0:
        return 0.0, 0.0
    s = max(d - offset, _REP_MIN)
    mag = gain * (1.0 / s - 1.0 / reach) / (s * s)
    return mag * (px - qx) / d, mag * (py - qy) / d


@njit(cache=True)
def evader_repulsion(px, py, rects, width, height, gain, reach, offset):
    """Sum of repulsions from the nearest point of each wall and bar within reach."""
    fx, fy = 0.0, 0.0
    # walls: left, right, bottom, top
    gx, gy = _repulse(px, py, 0.0, py, px, gain, reach, offset)
    fx += gx
    fy += gy
    gx, gy = _repulse(px, py, width, py, width - px, gain, reach, offset)
    fx += gx
    fy += gy
    gx, gy = _repulse(px, py, px, 0.0, py, gain, reach, offset)
    fx += gx
    fy += gy
    gx, gy = _repulse(px, py, px, height, height - py, gain, reach, offset)
    fx += gx
    fy += gy
    for k in range(rects.shape[0]):
        cx = min(max(px, rects[k, 0]), rects[k, 2])
        cy = min(max(py, rects[k, 1]), rects[k, 3])
        d = norm(px - cx, py - cy)
        gx, gy = _repulse(px, py, cx, cy, d, gain, reach, offset)
        fx += gx
        fy += gy
    return fx, fy


# ---- reset ------------------------------------------------------------------------------
@njit(cache=True)
def _place(rng, b, out, n, region, separation):
    """Rejection-sample n points in region (x0, x1, y0, y1), pairwise ≥ separation apart."""
    for k in range(n):
        for _ in range(100000):
            x = region[0] + _rng.uniform(rng, b) * (region[1] - region[0])
            y = region[2] + _rng.uniform(rng, b) * (region[3] - region[2])
            ok = True
            for j in range(k):
                if norm(x - out[j, 0], y - out[j, 1]) < separation:
                    ok = False
                    break
            if ok:
                break
        out[k, 0] = x
        out[k, 1] = y


@njit(cache=True)
def reset_episode(b, p, s):
    """Draw a fresh initial state for episode b from its own stream."""
    fp, ip, rects, spawn = p
    # fmt: off
    (ppos, phead, pactive, epos, ehead, ealive, wander_left, wander_dir, slip, slip_dir,
     t, done, collided, captures, ep_return, rng) = s
    # fmt: on
    _place(rng, b, ppos[b], ppos.shape[1], spawn[0], fp[F_SPAWN_SEP])
    _place(rng, b, epos[b], epos.shape[1], spawn[1], fp[F_SPAWN_SEP])
    for i in range(ppos.shape[1]):
        phead[b, i] = 0.5 * math.pi
        pactive[b, i] = True
        ep_return[b, i] = 0.0
    for e in range(epos.shape[1]):
        ehead[b, e] = -0.5 * math.pi
        ealive[b, e] = True
        wander_left[b, e] = 0
        wander_dir[b, e] = 0.0
        slip[b, e] = False
        slip_dir[b, e, 0] = 0.0
        slip_dir[b, e, 1] = 0.0
    t[b] = 0
    done[b] = False
    collided[b] = False
    captures[b] = 0


@njit(cache=True, parallel=True)
def reset_masked(mask, p, s, obs):
    """Reset every episode b with mask[b] and write its first observation."""
    for b in prange(mask.shape[0]):
        if mask[b]:
            reset_episode(b, p, s)
            observe(b, p, s, obs)


# ---- observation --------------------------------------------------------------------------
@njit(cache=True)
def observe(b, p, s, obs):
    """Write every pursuer's egocentric observation of episode b into obs[b] (SPEC §1)."""
    fp, ip, rects, spawn = p
    # fmt: off
    (ppos, phead, pactive, epos, ehead, ealive, wander_left, wander_dir, slip, slip_dir,
     t, done, collided, captures, ep_return, rng) = s
    # fmt: on
    n_p = ppos.shape[1]
    n_e = epos.shape[1]
    scale = fp[F_OBS_SCALE]
    far = fp[F_UNOBSERVED]
    width = fp[F_WIDTH]
    height = fp[F_HEIGHT]
    for i in range(n_p):
        px = ppos[b, i, 0]
        py = ppos[b, i, 1]
        h = phead[b, i]
        k = 0
        for e in range(n_e):
            if ealive[b, e]:
                dx = epos[b, e, 0] - px
                dy = epos[b, e, 1] - py
                obs[b, i, k] = norm(dx, dy) / scale
                obs[b, i, k + 1] = wrap(math.atan2(dy, dx) - h) / math.pi
                obs[b, i, k + 2] = wrap(ehead[b, e] - h) / math.pi
            else:
                obs[b, i, k] = far
                obs[b, i, k + 1] = 0.0
                obs[b, i, k + 2] = 0.0
            k += 3
        qx, qy, d = nearest_static(px, py, rects, width, height)
        for j in range(n_p):
            if j != i and not pactive[b, j]:
                dj = norm(ppos[b, j, 0] - px, ppos[b, j, 1] - py)
                if dj < d:
                    qx, qy, d = ppos[b, j, 0], ppos[b, j, 1], dj
        obs[b, i, k] = d / scale
        obs[b, i, k + 1] = wrap(math.atan2(qy - py, qx - px) - h) / math.pi if d > 0.0 else 0.0
        k += 2
        for j in range(n_p):
            if j == i:
                continue
            dx = ppos[b, j, 0] - px
            dy = ppos[b, j, 1] - py
            d = norm(dx, dy)
            if pactive[b, j] and d <= fp[F_PERCEPTION]:
                obs[b, i, k] = d / scale
                obs[b, i, k + 1] = wrap(math.atan2(dy, dx) - h) / math.pi
            else:
                obs[b, i, k] = far
                obs[b, i, k + 1] = 0.0
            k += 2
        obs[b, i, k] = px / width
        obs[b, i, k + 1] = py / height
        obs[b, i, k + 2] = math.cos(h)
        obs[b, i, k + 3] = math.sin(h)


# ---- evader (SPEC §2) --------------------------------------------------------------------
@njit(cache=True)
def evader_heading(b, e, p, s):
    """The DACOOP escaper's new heading for evader e of episode b, from the true state.

    Wander when calm and clear of obstacles; otherwise flee from the pursuers within the
    sensitivity range, pushed off obstacles; follow the wall when flight and repulsion
    oppose; slip between two close pursuers when the gap is reachable first. The heading
    change is bounded by the evader's max turn.
    """
    fp, ip, rects, spawn = p
    # fmt: off
    (ppos, phead, pactive, epos, ehead, ealive, wander_left, wander_dir, slip, slip_dir,
     t, done, collided, captures, ep_return, rng) = s
    # fmt: on
    n_p = ppos.shape[1]
    ex = epos[b, e, 0]
    ey = epos[b, e, 1]
    h = ehead[b, e]
    hx = math.cos(h)
    hy = math.sin(h)
    sens = fp[F_E_SENS]

    # flee force and the two nearest active pursuers
    flee_x, flee_y = 0.0, 0.0
    n_flee = 0
    n_slip = 0
    d1, d2 = np.inf, np.inf
    i1, i2 = -1, -1
    for i in range(n_p):
        if not pactive[b, i]:
            continue
        ax = ex - ppos[b, i, 0]
        ay = ey - ppos[b, i, 1]
        d = norm(ax, ay)
        if d < sens and d > 0.0:
            flee_x += ax / (d * d)
            flee_y += ay / (d * d)
            n_flee += 1
        if d < fp[F_E_SLIP_RANGE]:
            n_slip += 1
        if d < d1:
            d2, i2 = d1, i1
            d1, i1 = d, i
        elif d < d2:
            d2, i2 = d, i
    d_min = d1

    _, _, d_obs = nearest_static(ex, ey, rects, fp[F_WIDTH], fp[F_HEIGHT])
    rep_x, rep_y = evader_repulsion(
        ex,
        ey,
        rects,
        fp[F_WIDTH],
        fp[F_HEIGHT],
        fp[F_E_REP_GAIN],
        fp[F_E_REP_RANGE],
        fp[F_E_REP_OFFSET],
    )

    panic = 0.0
    if d_min < sens:
        panic = (math.exp(1.0 - d_min / sens) - 1.0) / (_E - 1.0)

    if panic < fp[F_E_PANIC] and d_obs > fp[F_E_WANDER_CLEAR]:
        if wander_left[b, e] <= 0:
            wander_dir[b, e] = wrap(h + (_rng.uniform(rng, b) - 0.5) * math.pi)
            wander_left[b, e] = _rng.integer(rng, b, ip[I_HOLD_MIN], ip[I_HOLD_MAX])
        wander_left[b, e] -= 1
        esc_x = math.cos(wander_dir[b, e])
        esc_y = math.sin(wander_dir[b, e])
    else:
        wander_left[b, e] = 0
        flee_norm = norm(flee_x, flee_y)
        if n_flee > 0 and flee_norm > 0.0:
            esc_x, esc_y = flee_x / flee_norm, flee_y / flee_norm
        else:
            esc_x, esc_y = 0.0, 0.0

    tot_x = esc_x + rep_x
    tot_y = esc_y + rep_y
    if tot_x * esc_x + tot_y * esc_y < 0.0:
        # wall following: move along the obstacle tangent nearer the current heading
        r1x, r1y = -rep_y, rep_x
        r2x, r2y = rep_y, -rep_x
        against = -(esc_x * rep_x + esc_y * rep_y)
        if hx * r1x + hy * r1y > 0.0:
            tot_x, tot_y = r1x, r1y
            if d_min < fp[F_E_SWITCH] and 1.5 * (esc_x * r2x + esc_y * r2y) > against:
                tot_x, tot_y = r2x, r2y
        else:
            tot_x, tot_y = r2x, r2y
            if d_min < fp[F_E_SWITCH] and 1.5 * (esc_x * r1x + esc_y * r1y) > against:
                tot_x, tot_y = r1x, r1y
        if d_obs < fp[F_E_PUSH]:
            tot_x += rep_x
            tot_y += rep_y

    # slip between the two nearest pursuers (Janosov et al. 2017, DACOOP)
    if n_slip >= 2:
        a1x = ppos[b, i1, 0] - ex
        a1y = ppos[b, i1, 1] - ey
        a2x = ppos[b, i2, 0] - ex
        a2y = ppos[b, i2, 1] - ey
        gx = a1x + a2x
        gy = a1y + a2y
        gn = norm(gx, gy)
        reachable = False
        if gn > 0.0:
            gx /= gn
            gy /= gn
            p1 = gx * a1x + gy * a1y
            p2 = gx * a2x + gy * a2y
            tau_e1 = abs(p1) / fp[F_V_E]
            tau_e2 = abs(p2) / fp[F_V_E]
            tau_c1 = (norm(gx * p1 - a1x, gy * p1 - a1y) - fp[F_CAPTURE]) / fp[F_V_P]
            tau_c2 = (norm(gx * p2 - a2x, gy * p2 - a2y) - fp[F_CAPTURE]) / fp[F_V_P]
            reachable = tau_e1 < tau_c1 and tau_e2 < tau_c2
        if not slip[b, e]:
            if reachable and d_obs < fp[F_E_SLIP_START] and rep_x * gx + rep_y * gy >= 0.0:
                tot_x, tot_y = gx, gy
                slip_dir[b, e, 0] = gx
                slip_dir[b, e, 1] = gy
                slip[b, e] = True
        elif reachable and d_obs > fp[F_E_SLIP_KEEP]:
            if gx * slip_dir[b, e, 0] + gy * slip_dir[b, e, 1] >= 0.0:
                tot_x, tot_y = gx, gy
            else:
                tot_x, tot_y = -gx, -gy
        else:
            slip[b, e] = False
    else:
        slip[b, e] = False

    if tot_x == 0.0 and tot_y == 0.0:
        return h
    turn = wrap(math.atan2(tot_y, tot_x) - h)
    limit = fp[F_E_MAX_TURN]
    turn = min(max(turn, -limit), limit)
    return wrap(h + turn)


# ---- step -----------------------------------------------------------------------------------
@njit(cache=True)
def approach_term(b, i, p, s, dist_prev):
    """Pursuer i's Σ (d_prev − d_now) / approach_scale over the live evaders, d_now from
    the positions as they stand."""
    fp = p[0]
    ppos, epos, ealive = s[0], s[3], s[5]
    r = 0.0
    for e in range(epos.shape[1]):
        if ealive[b, e]:
            d = norm(epos[b, e, 0] - ppos[b, i, 0], epos[b, e, 1] - ppos[b, i, 1])
            r += (dist_prev[b, i, e] - d) / fp[F_APPROACH_SCALE]
    return r


@njit(cache=True)
def step_episode(b, actions, p, s, out):
    """Advance episode b by one step with pursuer actions [n_p] in [0, 1] (already clipped)."""
    fp, ip, rects, spawn = p
    # fmt: off
    (ppos, phead, pactive, epos, ehead, ealive, wander_left, wander_dir, slip, slip_dir,
     t, done, collided, captures, ep_return, rng) = s
    # fmt: on
    obs, reward, terminated, truncated, disabled, new_heading, dist_prev = out
    n_p = ppos.shape[1]
    n_e = epos.shape[1]
    for i in range(n_p):
        reward[b, i] = 0.0
        disabled[b, i] = False
    terminated[b] = False
    truncated[b] = False
    if done[b]:
        return
    t[b] += 1

    # distances before the move, for the approach term
    for i in range(n_p):
        for e in range(n_e):
            dist_prev[b, i, e] = norm(epos[b, e, 0] - ppos[b, i, 0], epos[b, e, 1] - ppos[b, i, 1])

    # evaders decide on the state before anyone moves (simultaneous moves)
    for e in range(n_e):
        if ealive[b, e]:
            new_heading[b, e] = evader_heading(b, e, p, s)

    step_p = fp[F_V_P] * fp[F_DT]
    for i in range(n_p):
        if pactive[b, i]:
            h = wrap(phead[b, i] + (2.0 * actions[b, i] - 1.0) * fp[F_MAX_TURN])
            phead[b, i] = h
            ppos[b, i, 0] += step_p * math.cos(h)
            ppos[b, i, 1] += step_p * math.sin(h)

    # the approach term credited to the pursuer's own move: to where the evaders were
    if fp[F_APPROACH_OWN] > 0.0:
        for i in range(n_p):
            if pactive[b, i]:
                reward[b, i] = approach_term(b, i, p, s, dist_prev)

    step_e = fp[F_V_E] * fp[F_DT]
    for e in range(n_e):
        if ealive[b, e]:
            h = new_heading[b, e]
            ehead[b, e] = h
            nx = epos[b, e, 0] + step_e * math.cos(h)
            ny = epos[b, e, 1] + step_e * math.sin(h)
            _, _, clearance = nearest_static(nx, ny, rects, fp[F_WIDTH], fp[F_HEIGHT])
            if clearance >= fp[F_E_MIN_CLEAR]:
                epos[b, e, 0] = nx
                epos[b, e, 1] = ny

    # approach term over the evaders live at the start of the step (after both moves)
    if fp[F_APPROACH_OWN] == 0.0:
        for i in range(n_p):
            if pactive[b, i]:
                reward[b, i] = approach_term(b, i, p, s, dist_prev)

    # captures, by any pursuer active this step; the bonus is shared by every active pursuer
    caught = 0
    for e in range(n_e):
        if not ealive[b, e]:
            continue
        for i in range(n_p):
            if pactive[b, i]:
                d = norm(epos[b, e, 0] - ppos[b, i, 0], epos[b, e, 1] - ppos[b, i, 1])
                if d < fp[F_CAPTURE]:
                    ealive[b, e] = False
                    caught += 1
                    break
    if caught > 0:
        captures[b] += caught
        for i in range(n_p):
            if pactive[b, i]:
                reward[b, i] += fp[F_CAPTURE_REWARD] * caught

    # collisions: walls, bars and disabled pursuers (safe radius); active pairs (κ);
    # and the proximity penalties (obstacles, disabled pursuers; active teammates)
    any_collision = False
    for i in range(n_p):
        if not pactive[b, i]:
            continue
        px = ppos[b, i, 0]
        py = ppos[b, i, 1]
        _, _, d = nearest_static(px, py, rects, fp[F_WIDTH], fp[F_HEIGHT])
        hit = d < fp[F_SAFE]
        near_obstacle = d < fp[F_OBSTACLE_REACH]
        near_mates = 0
        for j in range(n_p):
            if j == i:
                continue
            dj = norm(ppos[b, j, 0] - px, ppos[b, j, 1] - py)
            if pactive[b, j]:
                hit = hit or dj < fp[F_KAPPA]
                if dj < fp[F_MATE_REACH]:
                    near_mates += 1
            else:
                hit = hit or dj < fp[F_SAFE]
                near_obstacle = near_obstacle or dj < fp[F_OBSTACLE_REACH]
        if near_obstacle:
            reward[b, i] -= fp[F_OBSTACLE_PENALTY]
        reward[b, i] -= fp[F_MATE_PENALTY] * near_mates
        disabled[b, i] = hit
        if hit:
            reward[b, i] -= fp[F_COLLISION_PENALTY]
            any_collision = True
    if any_collision:
        collided[b] = True
        for i in range(n_p):
            if disabled[b, i]:
                pactive[b, i] = False

    for i in range(n_p):
        ep_return[b, i] += reward[b, i]

    all_caught = captures[b] >= n_e
    all_down = True
    for i in range(n_p):
        if pactive[b, i]:
            all_down = False
    if all_caught or all_down:
        terminated[b] = True
        done[b] = True
    elif t[b] >= ip[I_HORIZON]:
        truncated[b] = True
        done[b] = True

    observe(b, p, s, obs)


@njit(cache=True, parallel=True)
def step_all(actions, p, s, out):
    """Advance every episode of the batch by one step, in parallel over episodes."""
    for b in prange(actions.shape[0]):
        step_episode(b, actions, p, s, out)


@njit(cache=True, parallel=True)
def observe_all(mask, p, s, obs):
    """Recompute the observation of every episode b with mask[b]."""
    for b in prange(mask.shape[0]):
        if mask[b]:
            observe(b, p, s, obs)
