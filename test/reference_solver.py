"""An independent, slow solution of the friction oscillator for checking the physics core.

Sliding phases are integrated by scipy's DOP853 at tight tolerances with a terminal event at
zero velocity; at rest, the break-away instant is found on the sample grid (the force is
linear between samples, so the net force is too). Nothing here shares code with
fmm_ros.core: it is the textbook formulation, written out again.
"""

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp


@dataclass(frozen=True)
class Oscillator:
    """m x'' + c x' + k x + k3 x^3 + s N (mu_s + dmu exp(-(|v|/vs)^delta)) = f, s = sgn(v)."""

    mass: float
    damping: float
    stiffness: float
    normal_force: float
    mu_pos: float
    mu_neg: float
    cubic: float = 0.0
    static_excess: float = 0.0
    stribeck_velocity: float = 1.0
    stribeck_exponent: float = 2.0

    def spring(self, x):
        return self.stiffness * x + self.cubic * x**3

    def friction(self, sigma, v):
        mu = self.mu_pos if sigma > 0 else self.mu_neg
        ratio = np.abs(v) / self.stribeck_velocity
        excess = self.static_excess * np.exp(-(ratio**self.stribeck_exponent))
        return self.normal_force * (mu + excess)

    def static_limit(self, sigma):
        return self.friction(sigma, 0.0)


def solve(osc: Oscillator, force, rate_hz, x0=0.0, v0=0.0):
    """(displacement, velocity) on the sample grid."""
    t_grid = np.arange(force.size) / rate_hz
    end = t_grid[-1]

    def applied(t):
        return np.interp(t, t_grid, force)

    def rhs(sigma):
        def f(t, z):
            return [
                z[1],
                (
                    applied(t)
                    - osc.damping * z[1]
                    - osc.spring(z[0])
                    - sigma * osc.friction(sigma, z[1])
                )
                / osc.mass,
            ]

        return f

    def stop(t, z):
        return z[1]

    stop.terminal = True

    pieces = []  # (start, end, None for rest at x / dense solution)
    t, x, v = 0.0, x0, v0
    sigma = np.sign(v)
    while t < end:
        if sigma == 0:
            net = applied(t) - osc.spring(x)
            if -osc.static_limit(-1) <= net <= osc.static_limit(1):
                g = force - osc.spring(x)
                out = (g > osc.static_limit(1)) | (g < -osc.static_limit(-1))
                later = np.flatnonzero(out & (t_grid > t))
                if later.size == 0:
                    pieces.append((t, end, x))
                    break
                i = later[0]
                sigma = np.sign(g[i])
                edge = sigma * osc.static_limit(sigma)
                t_a = max(t, t_grid[i - 1])
                g_a = applied(t_a) - osc.spring(x)
                t_break = t_a + (t_grid[i] - t_a) * (edge - g_a) / (g[i] - g_a)
                pieces.append((t, t_break, x))
                t = t_break
            else:
                sigma = np.sign(net)
        stop.direction = -sigma
        sol = solve_ivp(
            rhs(sigma),
            (t, end),
            [x, v],
            method='DOP853',
            rtol=1e-12,
            atol=1e-15,
            events=stop,
            dense_output=True,
            max_step=2.0 / rate_hz,
            first_step=1e-9,
        )
        pieces.append((t, sol.t[-1], sol.sol))
        if sol.status != 1:
            break
        t = sol.t_events[0][-1]
        x, v = sol.y_events[0][-1][0], 0.0
        sigma = 0  # the stick test above decides rest or reversal
    displacement = np.empty(force.size)
    velocity = np.empty(force.size)
    for start, stop_t, piece in pieces:
        sel = (t_grid >= start) & (t_grid <= stop_t)
        if callable(piece):
            displacement[sel], velocity[sel] = piece(t_grid[sel])
        else:
            displacement[sel], velocity[sel] = piece, 0.0
    return displacement, velocity
