"""The DACOOP escaper (docs/contract.md §2), compiled: its repulsion from walls and bars and its
heading decision, called by `hola_ray.env._kernels.step_episode` for every live evader."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from hola_ray.env import _rng
from hola_ray.env._arena import (
    F_CAPTURE,
    F_E_MAX_TURN,
    F_E_PANIC,
    F_E_PUSH,
    F_E_REP_GAIN,
    F_E_REP_OFFSET,
    F_E_REP_RANGE,
    F_E_SENS,
    F_E_SLIP_KEEP,
    F_E_SLIP_RANGE,
    F_E_SLIP_START,
    F_E_SWITCH,
    F_E_WANDER_CLEAR,
    F_HEIGHT,
    F_V_E,
    F_V_P,
    F_WIDTH,
    I_HOLD_MAX,
    I_HOLD_MIN,
    nearest_on_disc,
    nearest_static,
    statics,
)
from hola_ray.env.geometry import norm, wrap

_E = math.e
_REP_MIN = 0.005  # floor of (d − offset) in the repulsion, so a grazing evader stays finite


@njit(cache=True, inline="always")
def _repulse(px, py, qx, qy, d, gain, reach, offset):
    """DACOOP obstacle repulsion from point q: gain·(1/(d−r) − 1/R)/(d−r)² along p − q."""
    if d >= reach or d <= 0.0:
        return 0.0, 0.0
    s = max(d - offset, _REP_MIN)
    mag = gain * (1.0 / s - 1.0 / reach) / (s * s)
    return mag * (px - qx) / d, mag * (py - qy) / d


@njit(cache=True)
def evader_repulsion(px, py, rects, discs, width, height, gain, reach, offset):
    """Sum of repulsions from the nearest point of each wall, box and disc within reach."""
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
    for k in range(discs.shape[0]):
        cx, cy, d = nearest_on_disc(px, py, discs[k, 0], discs[k, 1], discs[k, 2])
        gx, gy = _repulse(px, py, cx, cy, d, gain, reach, offset)
        fx += gx
        fy += gy
    return fx, fy


# ---- reset ------------------------------------------------------------------------------
# ---- evader (docs/contract.md §2) ----------------------------------------------------------------
@njit(cache=True, inline="always")
def _pursuers_near(b, ex, ey, p, s):
    """The flee force Σ (e − p)/d² over the active pursuers within the sensitivity range,
    their count, the count within the slip range, and the two nearest active pursuers
    (distance and index of the nearest; index of the second)."""
    fp, ppos, pactive = p.fp, s.ppos, s.pactive
    sens = fp[F_E_SENS]
    flee_x, flee_y = 0.0, 0.0
    n_flee = 0
    n_slip = 0
    d1, d2 = np.inf, np.inf
    i1, i2 = -1, -1
    for i in range(ppos.shape[1]):
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
    return flee_x, flee_y, n_flee, n_slip, d1, i1, i2


@njit(cache=True, inline="always")
def _escape(b, e, h, p, s, flee_x, flee_y, n_flee, d_min, d_obs):
    """The escape direction: a held random wander heading when calm (panic below its
    threshold) and clear of obstacles, else the normalised flee force."""
    fp, ip, rng = p.fp, p.ip, s.rng
    sens = fp[F_E_SENS]
    panic = 0.0
    if d_min < sens:
        panic = (math.exp(1.0 - d_min / sens) - 1.0) / (_E - 1.0)
    if panic < fp[F_E_PANIC] and d_obs > fp[F_E_WANDER_CLEAR]:
        if s.wander_left[b, e] <= 0:
            s.wander_dir[b, e] = wrap(h + (_rng.uniform(rng, b) - 0.5) * math.pi)
            s.wander_left[b, e] = _rng.integer(rng, b, ip[I_HOLD_MIN], ip[I_HOLD_MAX])
        s.wander_left[b, e] -= 1
        return math.cos(s.wander_dir[b, e]), math.sin(s.wander_dir[b, e])
    s.wander_left[b, e] = 0
    flee_norm = norm(flee_x, flee_y)
    if n_flee > 0 and flee_norm > 0.0:
        return flee_x / flee_norm, flee_y / flee_norm
    return 0.0, 0.0


@njit(cache=True, inline="always")
def _wall_follow(h, fp, esc_x, esc_y, rep_x, rep_y, d_min, d_obs):
    """Escape plus repulsion; when they oppose, move along the obstacle tangent nearer the
    current heading (the other one when a pursuer is close and it serves the escape
    better), pushed off the obstacle when very near."""
    hx = math.cos(h)
    hy = math.sin(h)
    tot_x = esc_x + rep_x
    tot_y = esc_y + rep_y
    if tot_x * esc_x + tot_y * esc_y < 0.0:
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
    return tot_x, tot_y


@njit(cache=True, inline="always")
def _slip(b, e, ex, ey, p, s, i1, i2, rep_x, rep_y, d_obs, tot_x, tot_y):
    """Slip between the two nearest pursuers (Janosov et al. 2017, DACOOP) when the gap
    is reachable before they close it: start near an obstacle that does not push against
    the gap, keep slipping while clear of obstacles, else stop. Returns the direction."""
    fp, ppos, slip, slip_dir = p.fp, s.ppos, s.slip, s.slip_dir
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
    return tot_x, tot_y


@njit(cache=True)
def evader_heading(b, e, p, s):
    """The DACOOP escaper's new heading for evader e of episode b, from the true state.

    Wander when calm and clear of obstacles; otherwise flee from the pursuers within the
    sensitivity range, pushed off obstacles; follow the wall when flight and repulsion
    oppose; slip between two close pursuers when the gap is reachable first. The heading
    change is bounded by the evader's max turn.
    """
    fp = p.fp
    rects, discs = statics(b, p, s)
    ex = s.epos[b, e, 0]
    ey = s.epos[b, e, 1]
    h = s.ehead[b, e]
    flee_x, flee_y, n_flee, n_slip, d_min, i1, i2 = _pursuers_near(b, ex, ey, p, s)
    _, _, d_obs = nearest_static(ex, ey, rects, discs, fp[F_WIDTH], fp[F_HEIGHT])
    rep_x, rep_y = evader_repulsion(
        ex,
        ey,
        rects,
        discs,
        fp[F_WIDTH],
        fp[F_HEIGHT],
        fp[F_E_REP_GAIN],
        fp[F_E_REP_RANGE],
        fp[F_E_REP_OFFSET],
    )
    esc_x, esc_y = _escape(b, e, h, p, s, flee_x, flee_y, n_flee, d_min, d_obs)
    tot_x, tot_y = _wall_follow(h, fp, esc_x, esc_y, rep_x, rep_y, d_min, d_obs)
    if n_slip >= 2:
        tot_x, tot_y = _slip(b, e, ex, ey, p, s, i1, i2, rep_x, rep_y, d_obs, tot_x, tot_y)
    else:
        s.slip[b, e] = False

    if tot_x == 0.0 and tot_y == 0.0:
        return h
    turn = wrap(math.atan2(tot_y, tot_x) - h)
    limit = fp[F_E_MAX_TURN]
    turn = min(max(turn, -limit), limit)
    return wrap(h + turn)
