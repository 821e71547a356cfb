"""Compiled per-episode physics of the pursuit arena: one loop over the batch, numba-jitted.

Everything here is plain arrays in, arrays out, grouped in three named tuples: `Params`
(constants), `Arena` (per-episode state) and `StepOut` (per-step outputs and scratch).
`core.BatchedPursuit` owns the arrays and is the only caller. The parameter vector `fp` is
indexed by the `F_*` constants of `hola_ray.env._arena` and filled by its `pack_params`;
obstacles arrive as `rects` [K, 4] = (x_min, y_min, x_max, y_max). The evader's decision
is `hola_ray.env._evader`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from hola_ray.env import _rng
from hola_ray.env._arena import (
    F_APPROACH_OWN,
    F_APPROACH_SCALE,
    F_CAPTURE,
    F_CAPTURE_REWARD,
    F_COLLISION_PENALTY,
    F_DT,
    F_E_MIN_CLEAR,
    F_HEIGHT,
    F_KAPPA,
    F_MATE_GRADED,
    F_MATE_PENALTY,
    F_MATE_REACH,
    F_MAX_TURN,
    F_OBS_SCALE,
    F_OBSTACLE_PENALTY,
    F_OBSTACLE_REACH,
    F_PERCEPTION,
    F_RESPONSE,
    F_SAFE,
    F_SHARED,
    F_SPAWN_SEP,
    F_TEAM_FROM,
    F_TEAM_TO,
    F_UNOBSERVED,
    F_V_E,
    F_V_P,
    F_WIDTH,
    I_ARENAS,
    I_HEADINGS,
    I_HORIZON,
    I_OBS_EVADERS,
    I_OBS_PURSUERS,
    I_RESPONSE_DELAY,
    I_TEAM_CHANGES,
    I_TEAM_FIXED,
    I_TEAM_MIN,
    I_TEAM_PRESENT,
    I_TEAM_PRESENT_HIGH,
    Arena,
    Params,
    StepOut,
    nearest_static,
    pack_params,
    statics,
)
from hola_ray.env._evader import evader_heading
from hola_ray.env.geometry import norm, wrap

__all__ = ["Arena", "Params", "StepOut", "observe_all", "pack_params", "reset_masked", "step_all"]


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
    fp, ip, rects, spawn, discs = p
    # fmt: off
    (ppos, phead, pactive, epos, ehead, ealive, wander_left, wander_dir, slip, slip_dir,
     t, done, collided, captures, ep_return, rng, pvel, pcmd, ppresent, pwaiting,
     change_t, team_rng, layout) = s
    # fmt: on
    if ip[I_ARENAS] > 1:  # a layout per episode (contract §6.1), drawn beside the stream:
        # the episode then starts and plays as it would in that arena alone, seeded alike
        layout[b] = _rng.integer_of(_rng.side(rng, b, _rng.LAYOUT), 0, ip[I_ARENAS] - 1)
    _place(rng, b, ppos[b], ppos.shape[1], spawn[0], fp[F_SPAWN_SEP])
    _place(rng, b, epos[b], epos.shape[1], spawn[1], fp[F_SPAWN_SEP])
    for i in range(ppos.shape[1]):
        phead[b, i] = 0.5 * math.pi
        pactive[b, i] = True
        ep_return[b, i] = 0.0
        for k in range(2):  # at rest, nothing commanded yet (the response model)
            pvel[b, i, k] = 0.0
            pcmd[b, i, k] = 0.0
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
    for i in range(ppos.shape[1]):
        ppresent[b, i] = True
        pwaiting[b, i] = False
    if ip[I_TEAM_PRESENT] < ppos.shape[1] or ip[I_TEAM_CHANGES] > 0:
        _open_team(b, ip, fp, s)


@njit(cache=True)
def _open_team(b, ip, fp, s):
    """Episode b's team as it starts, and when it will change (contract §6.3): all but
    `present` of the seats beyond the fixed ones wait out of play (`present` itself drawn
    in its range where it is one); the changes' steps are drawn in the window of the
    horizon, in order. The team's draws are the episode's but beside its stream (its start
    is drawn as the whole team's), and each change draws from a stream of its own, seeded
    here: which teammate leaves or where one joins does not hang on how the pursuers flew
    (only on who may leave), so two policies meet the same changes."""
    n_p = s.ppos.shape[1]
    team = s.team_rng[b]  # [0]: the start and the steps; [1 + k]: the k-th change's
    team[0] = _rng.side(s.rng, b, _rng.TEAM)
    present = ip[I_TEAM_PRESENT]
    if ip[I_TEAM_PRESENT_HIGH] > present:  # a team size per episode
        present = _rng.integer(team, 0, present, ip[I_TEAM_PRESENT_HIGH])
    waiting = n_p - present
    free = n_p - ip[I_TEAM_FIXED]
    for k in range(waiting):  # the k-th waiting seat: drawn among the free seats in play
        pick = _rng.integer(team, 0, 0, free - k - 1)
        for i in range(ip[I_TEAM_FIXED], n_p):
            if s.ppresent[b, i]:
                if pick == 0:
                    s.ppresent[b, i] = False
                    s.pactive[b, i] = False
                    s.pwaiting[b, i] = True
                    break
                pick -= 1
    horizon = ip[I_HORIZON]
    lo = max(1, int(fp[F_TEAM_FROM] * horizon))
    hi = max(lo, int(fp[F_TEAM_TO] * horizon))
    for k in range(ip[I_TEAM_CHANGES]):
        when = _rng.integer(team, 0, lo, hi)
        j = k
        while j > 0 and s.change_t[b, j - 1] > when:  # insertion: the steps in order
            s.change_t[b, j] = s.change_t[b, j - 1]
            j -= 1
        s.change_t[b, j] = when
    for k in range(ip[I_TEAM_CHANGES]):
        team[1 + k] = _rng.next_u64(team, 0)


@njit(cache=True, parallel=True)
def reset_masked(mask, p, s, obs):
    """Reset every episode b with mask[b] and write its first observation."""
    for b in prange(mask.shape[0]):
        if mask[b]:
            e = np.uint64(b)  # one compiled callee, not two (see step_all)
            reset_episode(e, p, s)
            observe(e, p, s, obs)


# ---- observation --------------------------------------------------------------------------
@njit(cache=True)
def observe(b, p, s, obs):
    """Write every pursuer's egocentric observation of episode b into obs[b] (contract §1)."""
    fp, ip, _, spawn, _ = p
    # fmt: off
    (ppos, phead, pactive, epos, ehead, ealive, wander_left, wander_dir, slip, slip_dir,
     t, done, collided, captures, ep_return, rng, pvel, pcmd, ppresent, pwaiting,
     change_t, team_rng, layout) = s
    # fmt: on
    rects, discs = statics(b, p, s)
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
        for _ in range(n_e, ip[I_OBS_EVADERS]):  # slots beyond the scenario: captured
            obs[b, i, k] = far
            obs[b, i, k + 1] = 0.0
            obs[b, i, k + 2] = 0.0
            k += 3
        qx, qy, d = nearest_static(px, py, rects, discs, width, height)
        for j in range(n_p):
            if j != i and not pactive[b, j] and ppresent[b, j]:  # a crashed one, in play
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
        for _ in range(n_p, ip[I_OBS_PURSUERS]):  # slots beyond the team: unobserved
            obs[b, i, k] = far
            obs[b, i, k + 1] = 0.0
            k += 2
        obs[b, i, k] = px / width
        obs[b, i, k + 1] = py / height
        obs[b, i, k + 2] = math.cos(h)
        obs[b, i, k + 3] = math.sin(h)
        k += 4
        if ip[I_HEADINGS]:
            for j in range(n_p):
                if j == i:
                    continue
                d = norm(ppos[b, j, 0] - px, ppos[b, j, 1] - py)
                seen = pactive[b, j] and d <= fp[F_PERCEPTION]
                obs[b, i, k] = wrap(phead[b, j] - h) / math.pi if seen else 0.0
                k += 1
            for _ in range(n_p, ip[I_OBS_PURSUERS]):
                obs[b, i, k] = 0.0
                k += 1


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


@njit(cache=True, inline="always")
def _move_pursuers(b, actions, placed, p, s):
    """Each active pursuer turns by (2a − 1)·max_turn and moves at its speed; or, when
    `placed` holds the batch's positions (flown by outside dynamics), turns and is put
    where it flew."""
    fp = p.fp
    step_p = fp[F_V_P] * fp[F_DT]
    beta = fp[F_RESPONSE]
    delayed = p.ip[I_RESPONSE_DELAY] > 0
    for i in range(s.ppos.shape[1]):
        if s.pactive[b, i]:
            h = wrap(s.phead[b, i] + (2.0 * actions[b, i] - 1.0) * fp[F_MAX_TURN])
            s.phead[b, i] = h
            if placed.shape[0] > 0:
                s.ppos[b, i, 0] = placed[b, i, 0]
                s.ppos[b, i, 1] = placed[b, i, 1]
            elif beta >= 1.0 and not delayed:
                s.ppos[b, i, 0] += step_p * math.cos(h)
                s.ppos[b, i, 1] += step_p * math.sin(h)
            else:
                _respond(b, i, h, beta, delayed, fp, s)


@njit(cache=True, inline="always")
def _respond(b, i, h, beta, delayed, fp, s):
    """The response model: the pursuer's velocity goes `beta` of the way to the velocity
    its heading commands (the one commanded a step ago when `delayed`), then it moves."""
    cx = fp[F_V_P] * math.cos(h)
    cy = fp[F_V_P] * math.sin(h)
    tx, ty = cx, cy
    if delayed:
        tx = s.pcmd[b, i, 0]
        ty = s.pcmd[b, i, 1]
        s.pcmd[b, i, 0] = cx
        s.pcmd[b, i, 1] = cy
    s.pvel[b, i, 0] += beta * (tx - s.pvel[b, i, 0])
    s.pvel[b, i, 1] += beta * (ty - s.pvel[b, i, 1])
    s.ppos[b, i, 0] += fp[F_DT] * s.pvel[b, i, 0]
    s.ppos[b, i, 1] += fp[F_DT] * s.pvel[b, i, 1]


@njit(cache=True, inline="always")
def _move_evaders(b, p, s, new_heading):
    """Each live evader takes its decided heading; a move that would end closer than
    min_clearance to a wall or bar is not made."""
    fp = p.fp
    rects, discs = statics(b, p, s)
    step_e = fp[F_V_E] * fp[F_DT]
    for e in range(s.epos.shape[1]):
        if s.ealive[b, e]:
            h = new_heading[b, e]
            s.ehead[b, e] = h
            nx = s.epos[b, e, 0] + step_e * math.cos(h)
            ny = s.epos[b, e, 1] + step_e * math.sin(h)
            _, _, clearance = nearest_static(nx, ny, rects, discs, fp[F_WIDTH], fp[F_HEIGHT])
            if clearance >= fp[F_E_MIN_CLEAR]:
                s.epos[b, e, 0] = nx
                s.epos[b, e, 1] = ny


@njit(cache=True, inline="always")
def _approach(b, p, s, reward, dist_prev):
    """The approach term of every active pursuer (`approach_term`)."""
    for i in range(s.ppos.shape[1]):
        if s.pactive[b, i]:
            reward[b, i] = approach_term(b, i, p, s, dist_prev)


@njit(cache=True, inline="always")
def _captures(b, p, s, reward):
    """Captures, by any pursuer active this step; the bonus is shared by every active
    pursuer."""
    fp, ppos, pactive = p.fp, s.ppos, s.pactive
    n_p = ppos.shape[1]
    caught = 0
    for e in range(s.epos.shape[1]):
        if not s.ealive[b, e]:
            continue
        for i in range(n_p):
            if pactive[b, i]:
                d = norm(s.epos[b, e, 0] - ppos[b, i, 0], s.epos[b, e, 1] - ppos[b, i, 1])
                if d < fp[F_CAPTURE]:
                    s.ealive[b, e] = False
                    caught += 1
                    break
    if caught > 0:
        s.captures[b] += caught
        for i in range(n_p):
            if pactive[b, i]:
                reward[b, i] += fp[F_CAPTURE_REWARD] * caught


@njit(cache=True, inline="always")
def _collisions(b, p, s, reward, disabled):
    """Collisions: walls, bars and disabled pursuers (safe radius); active pairs (κ); and
    the proximity penalties (obstacles, disabled pursuers; active teammates). A pursuer
    that collided is disabled."""
    fp, ppos, pactive = p.fp, s.ppos, s.pactive
    rects, discs = statics(b, p, s)
    n_p = ppos.shape[1]
    any_collision = False
    for i in range(n_p):
        if not pactive[b, i]:
            continue
        px = ppos[b, i, 0]
        py = ppos[b, i, 1]
        _, _, d = nearest_static(px, py, rects, discs, fp[F_WIDTH], fp[F_HEIGHT])
        hit = d < fp[F_SAFE]
        near_obstacle = d < fp[F_OBSTACLE_REACH]
        near_mates = 0.0
        for j in range(n_p):
            if j == i:
                continue
            dj = norm(ppos[b, j, 0] - px, ppos[b, j, 1] - py)
            if pactive[b, j]:
                hit = hit or dj < fp[F_KAPPA]
                if dj < fp[F_MATE_REACH]:
                    if fp[F_MATE_GRADED] > 0.0:
                        span = fp[F_MATE_REACH] - fp[F_KAPPA]
                        near_mates += min(1.0, (fp[F_MATE_REACH] - dj) / span) if span > 0 else 1.0
                    else:
                        near_mates += 1.0
            elif s.ppresent[b, j]:  # a crashed pursuer is an obstacle; a landed one is not
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
        s.collided[b] = True
        for i in range(n_p):
            if disabled[b, i]:
                pactive[b, i] = False


@njit(cache=True, inline="always")
def _share(b, s, reward, disabled):
    """The common reward (`RewardConfig.shared`): every pursuer active at the start of the
    step (those disabled by it included) receives the team's reward for the step, the sum
    of every pursuer's own terms, divided by the pursuers in play (n_p in the paper's team)."""
    n_p = s.ppos.shape[1]
    team, in_play = 0.0, 0
    for i in range(n_p):
        team += reward[b, i]
        in_play += s.ppresent[b, i]
    for i in range(n_p):
        if s.pactive[b, i] or disabled[b, i]:
            reward[b, i] = team / max(in_play, 1)


@njit(cache=True)
def _change_team(b, p, s):
    """The team's changes due at the end of this step: a teammate in play, not crashed and
    not in a fixed seat leaves (while more than `min_team` fly), or a waiting one joins at
    the pursuers' spawn, heading +y; a coin from the episode's stream decides where both
    can happen; the coin, the pick and the joiner's spot from the change's own stream."""
    ip = p.ip
    n_p = s.ppos.shape[1]
    team = s.team_rng[b]
    for k in range(s.change_t.shape[1]):
        if s.change_t[b, k] != s.t[b]:
            continue
        flying, leavers, joiners = 0, 0, 0
        for i in range(n_p):
            flying += s.pactive[b, i]
            leavers += s.pactive[b, i] and i >= ip[I_TEAM_FIXED]
            joiners += s.pwaiting[b, i]
        can_leave = leavers > 0 and flying > ip[I_TEAM_MIN]
        if not can_leave and joiners == 0:
            continue
        leave = can_leave and (joiners == 0 or _rng.uniform(team, 1 + k) < 0.5)
        pick = _rng.integer(team, 1 + k, 0, (leavers if leave else joiners) - 1)
        for i in range(n_p):
            eligible = (s.pactive[b, i] and i >= ip[I_TEAM_FIXED]) if leave else s.pwaiting[b, i]
            if not eligible:
                continue
            if pick > 0:
                pick -= 1
                continue
            if leave:
                s.pactive[b, i] = False
                s.ppresent[b, i] = False
            else:
                _join(b, i, p, s, team, 1 + k)
            break


@njit(cache=True)
def _join(b, i, p, s, stream, k):
    """Seat i comes into play at a point of the pursuers' spawn region, clear of the
    pursuers in play by the spawn separation where 1,000 draws (from `stream[k]`) find one."""
    fp, region = p.fp, p.spawn[0]
    for _ in range(1000):
        x = region[0] + _rng.uniform(stream, k) * (region[1] - region[0])
        y = region[2] + _rng.uniform(stream, k) * (region[3] - region[2])
        clear = True
        for j in range(s.ppos.shape[1]):
            if (
                s.ppresent[b, j]
                and norm(x - s.ppos[b, j, 0], y - s.ppos[b, j, 1]) < fp[F_SPAWN_SEP]
            ):
                clear = False
        if clear:
            break
    s.ppos[b, i, 0] = x
    s.ppos[b, i, 1] = y
    s.phead[b, i] = 0.5 * math.pi
    for k in range(2):
        s.pvel[b, i, k] = 0.0
        s.pcmd[b, i, k] = 0.0
    s.pactive[b, i] = True
    s.ppresent[b, i] = True
    s.pwaiting[b, i] = False


@njit(cache=True)
def step_episode(b, actions, placed, p, s, out):
    """Advance episode b by one step with pursuer actions [n_p] in [0, 1] (already clipped);
    `placed`: [B, n_p, 2] where outside dynamics flew the pursuers, or empty (kinematic)."""
    fp, ip = p.fp, p.ip
    obs, reward, terminated, truncated, disabled, new_heading, dist_prev = out
    ppos, epos, pactive, done, t = s.ppos, s.epos, s.pactive, s.done, s.t
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
        if s.ealive[b, e]:
            new_heading[b, e] = evader_heading(b, e, p, s)

    _move_pursuers(b, actions, placed, p, s)
    if fp[F_APPROACH_OWN] > 0.0:  # credited to the pursuer's own move: to where they were
        _approach(b, p, s, reward, dist_prev)
    _move_evaders(b, p, s, new_heading)
    if fp[F_APPROACH_OWN] == 0.0:  # over the evaders live at the start (after both moves)
        _approach(b, p, s, reward, dist_prev)
    _captures(b, p, s, reward)
    _collisions(b, p, s, reward, disabled)
    if fp[F_SHARED] > 0.0:
        _share(b, s, reward, disabled)

    for i in range(n_p):
        s.ep_return[b, i] += reward[b, i]

    all_caught = s.captures[b] >= n_e
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
    if ip[I_TEAM_CHANGES] > 0 and not done[b]:  # after the step's rewards: a joiner acts next
        _change_team(b, p, s)

    observe(b, p, s, obs)


@njit(cache=True, parallel=True)
def step_all(actions, placed, p, s, out):
    """Advance every episode of the batch by one step, in parallel over episodes.

    The callee gets the episode as uint64: numba types a prange body twice, the loop as
    written (an int64 index) and the parallel loop it runs (a uint64 one), and would compile
    every callee for both, the int64 copy never run. Cast, it compiles one (the copy that
    runs), in half the time."""
    for b in prange(actions.shape[0]):
        step_episode(np.uint64(b), actions, placed, p, s, out)


@njit(cache=True, parallel=True)
def observe_all(mask, p, s, obs):
    """Recompute the observation of every episode b with mask[b]."""
    for b in prange(mask.shape[0]):
        if mask[b]:
            observe(np.uint64(b), p, s, obs)  # one compiled callee (see step_all)
