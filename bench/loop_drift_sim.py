#!/usr/bin/env python3
"""How far can one loop closure lower the ATE of a drifting trajectory? A 2-D Monte-Carlo model of
the synthetic loop route (`pcr_orb synth --route loop`: ~600 frames 0.8 m apart, four left turns,
back at the start from frame ~507), for bench_loop's "ATE on/off" and its oracle.

Per draw: the estimate integrates the true steps with noise (translation noise per step and/or a
heading random walk, or a constant heading bias); the correction at the revisit removes the
heading error seen at frame CLOSE spread evenly over the steps before it (the maximum-likelihood
answer for independent heading noise), re-integrates, then spreads the remaining position error
at CLOSE evenly over the same steps (the same for translation noise); frames after CLOSE move
with it. ATE: RMSE after a rigid (SE(2)) alignment, as bench_loop's SE(3) ATE.

  python3 bench/loop_drift_sim.py [--draws 300] [--seed 1]
Prints, per noise kind, the mean ATE off/on, the median ratio on/off and the share of draws at or
below 1/3. Needs numpy (python3-numpy).
"""
import argparse

import numpy as np

CLOSE = 507


def route(n=600, step=0.8, sides=(100, 84, 132, 84, 32)):
    points, x, heading, side, left = [], np.zeros(2), 0.0, 0, sides[0]
    for _ in range(n):
        points.append(x.copy())
        x = x + step * np.array([np.sin(heading), np.cos(heading)])
        left -= step
        if left <= 0 and side < len(sides) - 1:
            side += 1
            left = sides[side]
            heading -= np.pi / 2
    return np.array(points)


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
    truth = route()
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
            fixed_dh[:CLOSE] -= np.cumsum(dh)[CLOSE - 1] / CLOSE
            corrected = integrate(fixed_dh, dt)
            weight = np.minimum(np.arange(len(corrected)), CLOSE) / CLOSE
            corrected -= weight[:, None] * (corrected[CLOSE] - truth[CLOSE])[None, :]
            off.append(ate(truth, estimate))
            on.append(ate(truth, corrected))
        ratio = np.array(on) / np.array(off)
        print("%-38s %9.4f %9.4f %12.3f %9.0f%%" % (name, np.mean(off), np.mean(on),
                                                     np.median(ratio), 100 * np.mean(ratio <= 1 / 3)))


if __name__ == "__main__":
    main()
