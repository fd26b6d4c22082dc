#!/usr/bin/env python3
"""How far can one loop closure lower the ATE of a drifting trajectory? A 2-D Monte-Carlo model of
the synthetic loop route as bench_loop renders it (`pcr_orb synth --route loop`, 600 frames at
10 Hz and 8 m/s, laps 1.15), for bench_loop's "ATE on/off" and its oracle.

The route is the ego's path of src/sim/scene_builder.cpp: the streets' centre lines form a
rectangle of 5.2 lx = 480 m / 1.15 round (lz = 1.6 lx), the ego lane runs 1.75 m outside them with
left-turn corner arcs of 12 m radius (a 410.8 m lap, 6.6 m shorter than the streets), and the
ego starts a quarter along the first straight. The revisit frame CLOSE is derived from that
route: the frame nearest to frame 0 in the first return (between a half and one and a half laps
on): frame 513, 0.39 m from it (frames 0.8 m apart); the script prints it.

Per draw: the estimate integrates the true steps with noise (translation noise per step and/or a
heading random walk, or a constant heading bias); the correction at the revisit removes the
heading error seen at frame CLOSE spread evenly over the steps before it (the maximum-likelihood
answer for independent heading noise), re-integrates, then spreads the remaining position error
at CLOSE evenly over the same steps (the same for translation noise); frames after CLOSE move
with it. ATE: RMSE after a rigid (SE(2)) alignment, as bench_loop's SE(3) ATE.

  python3 bench/loop_drift_sim.py [--draws 300] [--seed 1]
Prints the route and CLOSE, then per noise kind the mean ATE off/on, the median ratio on/off and
the share of draws at or below 1/3. Needs numpy (python3-numpy).
"""
import argparse

import numpy as np

# pcr_orb synth and bench_loop defaults (src/sim/synth_options.h, bench/bench_loop.cpp).
FRAMES, RATE_HZ, SPEED_MPS, LAPS = 600, 10.0, 8.0, 1.15
# src/sim/scene.h kLaneWidthM / 2 and src/sim/scene_builder.cpp kCornerRadiusM.
LANE_M, CORNER_RADIUS_M = 0.5 * 3.5, 12.0


def route(frames=FRAMES, rate_hz=RATE_HZ, speed=SPEED_MPS, laps=LAPS):
    """Frame positions (x, z) of the ego on the loop, as BuildScene and SyntheticWorld place it,
    and the length of one lap of its lane."""
    perimeter = max(speed * frames / rate_hz / laps, 1.0)
    lx = max(40.0, perimeter / 5.2)
    lz = 1.6 * lx
    x0, x1, z0, z1, r = LANE_M, -lx - LANE_M, -LANE_M, lz + LANE_M, CORNER_RADIUS_M
    # Pieces (length, curvature) from (x0, z0 + r), heading 0 (+z); negative curvature turns left.
    pieces = [(z1 - z0 - 2 * r, 0.0), (0.5 * np.pi * r, -1 / r),
              (x0 - x1 - 2 * r, 0.0), (0.5 * np.pi * r, -1 / r)] * 2
    starts, xz, heading = [], np.array([x0, z0 + r]), 0.0
    for length, k in pieces:
        starts.append((xz, heading))
        xz, heading = piece_at(xz, heading, k, length), heading + k * length
    lap = sum(length for length, _ in pieces)
    ends = np.cumsum([length for length, _ in pieces])
    s0 = 0.25 * (z1 - z0 - 2 * r)
    points = []
    for i in range(frames):
        s = (s0 + speed * i / rate_hz) % lap
        j = min(int(np.searchsorted(ends, s, side="right")), len(pieces) - 1)
        start, h0 = starts[j]
        points.append(piece_at(start, h0, pieces[j][1], s - (ends[j] - pieces[j][0])))
    return np.array(points), lap


def piece_at(start, h0, k, ds):
    """Path::Eval: a line (k == 0) or an arc of curvature k, ds along it."""
    if k == 0:
        return start + ds * np.array([np.sin(h0), np.cos(h0)])
    h = h0 + k * ds
    return start + np.array([np.cos(h0) - np.cos(h), np.sin(h) - np.sin(h0)]) / k


def revisit_frame(truth, lap, step):
    """The frame nearest to frame 0 between a half and one and a half laps on."""
    travelled = np.arange(len(truth)) * step
    window = np.flatnonzero((travelled > 0.5 * lap) & (travelled < 1.5 * lap))
    if len(window) == 0:
        raise SystemExit("the route does not come back to its start")
    return int(window[np.argmin(np.linalg.norm(truth[window] - truth[0], axis=1))])


def ate(truth, estimate):
    mt, me = truth.mean(0), estimate.mean(0)
    u, _, vt = np.linalg.svd((estimate - me).T @ (truth - mt))
    d = np.eye(2)
    if np.linalg.det(vt.T @ u.T) < 0:
        d[1, 1] = -1
    r = vt.T @ d @ u.T
    e = truth - ((r @ (estimate - me).T).T + mt)
    return np.sqrt((e**2).sum(1).mean())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=300)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    truth, lap = route()
    step = SPEED_MPS / RATE_HZ
    close = revisit_frame(truth, lap, step)
    print("route: %d frames, lap %.1f m, CLOSE = frame %d (%.2f m from frame 0)" %
          (len(truth), lap, close, np.linalg.norm(truth[close] - truth[0])))
    steps = np.diff(truth, axis=0)
    n = len(steps)

    def integrate(dh, dt):
        h = np.concatenate([[0], np.cumsum(dh)])[:-1]
        c, s = np.cos(h), np.sin(h)
        moved = np.stack([c * steps[:, 0] - s * steps[:, 1], s * steps[:, 0] + c * steps[:, 1]], 1)
        return np.vstack([truth[:1], truth[0] + np.cumsum(moved + dt, 0)])

    kinds = [("translation noise 2 mm/step", 0.002, 0.0, False),
             ("heading random walk 0.1 mrad/step", 0.0, 1e-4, False),
             ("both", 0.002, 1e-4, False),
             ("constant heading bias ~0.1 mrad/step", 0.0, 1e-4, True)]
    print("%-38s %9s %9s %12s %10s" % ("noise", "ATE off", "ATE on", "median on/off", "<= 1/3"))
    for name, sigma_t, sigma_h, bias in kinds:
        off, on = [], []
        for _ in range(args.draws):
            dh = np.full(n, rng.normal(0, sigma_h)) if bias else rng.normal(0, sigma_h, n)
            dt = rng.normal(0, sigma_t, (n, 2)) if sigma_t > 0 else np.zeros((n, 2))
            estimate = integrate(dh, dt)
            fixed_dh = dh.copy()
            fixed_dh[:close] -= np.cumsum(dh)[close - 1] / close
            corrected = integrate(fixed_dh, dt)
            weight = np.minimum(np.arange(len(corrected)), close) / close
            corrected -= weight[:, None] * (corrected[close] - truth[close])[None, :]
            off.append(ate(truth, estimate))
            on.append(ate(truth, corrected))
        ratio = np.array(on) / np.array(off)
        print("%-38s %9.4f %9.4f %12.3f %9.0f%%" % (name, np.mean(off), np.mean(on),
                                                     np.median(ratio), 100 * np.mean(ratio <= 1 / 3)))


if __name__ == "__main__":
    main()
