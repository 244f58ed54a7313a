"""The detector's odd nonlinearity learned online from the scan's own offset steps.

A quadrant photodiode's output bends towards the edge of its range: the catalogue's
``detector_nonlinearity`` reads r = θ + κ·θ³/θ_s² inside the range θ_s (the photodiode's
V + κ·V_c³/V_sat², Eq. 4.1 in angle units), so a controller that holds the reading on a
target θ* near the edge leaves the table κ·θ*³/θ_s² off it: 260 nm at 0.93·θ_lin for
κ = −0.057, nine times the benchmark's 30 nm band. The reading alone cannot tell
(``experiments/observability_bound.py``); the reading and the controller's own actions can.

In scan mode the table follows the offset, K·Δu (the stick plant, Eq. 4.4–4.7 at low
frequency), so an offset dither out by Δu and back, over two intervals, measures the
detector's local slope times K from its three readings r₀, r₁, r₂:

    g = (r₁ − r₀ − (r₂ − r₁)) / (2Δu) = K·(1 + 3κ·m²),   m = r̄/θ_s

(m² the mean of (θ/θ_s)² over the dither's span, θ the table angle behind the readings
r₀ and r₁, read through the cubic fitted so far; a drift of the reading or a creep of
the table, constant over the two intervals, cancels). K is the plant's scan gain,
unknown to within its stroke: dithers at two or more distances from the centre separate
it from κ. κ̂ is the least weighted squares of g − a·(1 + 3κ·m²(κ)), a profile over κ in
[−0.3, 0.3] with each dither's m² read through the κ tried (since stop 102: a span that
crosses θ_s, where the cubic stops and the slope is 1, has a second fixed point, which
the damped iteration used before it could land on), and its standard error that of
b/(3a) in the linear fit g = a + b·m² there, from the dithers' scatter, but never below a
relative scatter of
``REL_FLOOR`` between dithers nor the reading noise's share. A dither whose way back
differs from its way out by more than ``RETURN_TOL`` (and the noise) is not read: the
contacts slipped or the table crept, and the table did not follow the offset. The reading
is corrected, θ = r inverted through the cubic, only where the estimate is decided: at
least ``MIN_READ`` dithers read, the dithers' m² spread at least ``SPREAD_MIN``, and
|κ̂| ≥ ``KAPPA_MIN`` at ``Z_MIN`` standard errors. ``KAPPA_MIN`` (a slope 8 % steeper at
0.93 θ_lin) and ``REL_FLOOR`` stand above the scan gain's own change between a plant at
rest and one after stepping (a few per cent on held-out plants with little friction or
preload: ``python experiments/replay_episode.py closed_loop held_out edge_5um SEED``
prints each dither's slope); the catalogue's κ of 0.05–0.15 steepens the slope there by
13–39 %. Otherwise the reading passes unchanged, so a linear detector costs nothing but
the dithers.

Where the dithers come from is the controller's business (:mod:`controllers.base`: one
before the first step of an episode that starts inside the detector, and some after
arriving on a target near the edge).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["KAPPA_MIN", "REL_FLOOR", "RETURN_TOL", "SPREAD_MIN", "Z_MIN", "DetectorLinearity"]

# the smallest |κ| the reading is corrected for [-]: a slope 8 % steeper at the edge, above
# the scan gain's own change between a plant at rest and after stepping (up to 6 % on the
# held-out plants with little friction or preload)
KAPPA_MIN = 0.03
Z_MIN = 4.0  # standard errors |κ̂| must lie from 0
SPREAD_MIN = 0.02  # the dithers' spread of m² (standard deviation) [-]
REL_FLOOR = 0.015  # the least relative scatter of g between dithers [-] (that same change)
# a dither whose way back differs from its way out by more than this share (and the
# noise's 3σ) slipped or crept: the table did not follow the offset, and it is not read
RETURN_TOL = 0.03
MIN_DU = 0.5  # V, the smallest dither a slope is read from
MIN_READ = 4  # dithers read before κ̂ is decided (a floor vibration makes single ones err)


class DetectorLinearity:
    """Online κ of the detector's cubic from offset dithers, and the table angle behind a
    reading (module docstring). Angles in rad, offsets in V.

    Args:
        angle_range: θ_s, the table angle at the edge of the detector's linear range [rad].
        noise: the reading's white noise σ [rad] the lab expects (a floor on the scatter).
    """

    def __init__(self, angle_range: float, noise: float = 0.0) -> None:
        if not (math.isfinite(angle_range) and angle_range > 0.0):
            raise ValueError(f"angle_range={angle_range!r}: must be a positive angle [rad]")
        if not (math.isfinite(noise) and noise >= 0.0):
            raise ValueError(f"noise={noise!r}: must be a non-negative angle [rad]")
        self.theta_s = float(angle_range)
        self.noise = float(noise)
        self.reset()

    def reset(self) -> None:
        """Forget the dithers (a new episode: another plant may be behind the env)."""
        self._g: list[float] = []
        self._sd: list[float] = []
        self._span: list[tuple[float, float]] = []  # (r₀, r₁) [rad]
        self.rejected = 0  # dithers not read (their way back was not their way out)
        self._fit: tuple[float, float, bool] | None = (0.0, math.inf, False)
        self._gain = math.nan  # a of the last fit [rad/V]

    def add(self, du: float, readings: tuple[float, float, float], noise: float = 0.0) -> None:
        """One dither: offset step ``du`` [V] out and back, and the readings r₀, r₁, r₂
        [rad] before it, after the way out and after the way back; ``noise`` [rad] the
        reading's σ as the controller measures it (the larger of it and the expected one
        is used)."""
        r0, r1, r2 = (float(r) for r in readings)
        if abs(du) < MIN_DU or not all(math.isfinite(r) for r in (r0, r1, r2, noise)):
            return
        sigma = max(self.noise, float(noise))
        if abs(r2 - r0) > RETURN_TOL * abs(r1 - r0) + 3.0 * math.sqrt(2.0) * sigma:
            self.rejected += 1
            return
        self._g.append((2.0 * r1 - r0 - r2) / (2.0 * du))
        self._sd.append(math.sqrt(6.0) * sigma / (2.0 * abs(du)))
        self._span.append((r0, r1))
        self._fit = None

    @property
    def dithers(self) -> int:
        return len(self._g)

    def slopes(self) -> list[tuple[float, float]]:
        """The dithers read, as (m² [-] at κ̂ = 0, slope g [rad/V])."""
        return list(zip(self._m2(0.0).tolist(), self._g, strict=True)) if self._span else []

    def lever(self, m2: float) -> bool:
        """Whether a dither at ``m2`` = (r̄/θ_s)² [-] would pair with one read at an m² at
        most half or at least twice it: two such places separate κ from the scan gain."""
        if not self._span:
            return False
        have = self._m2(0.0)
        return bool(((have <= 0.5 * m2) | (have >= 2.0 * m2)).any())

    def _m2(self, kappa: float) -> np.ndarray:
        """Per dither, the mean over its span [θ(r₀), θ(r₁)] of (θ/θ_s)² where |θ| ≤ θ_s and
        of 0 beyond, where the cubic stops bending the slope (θ_c clipped: the reading
        runs on with slope 1), for a cubic of ``kappa`` (θ behind a reading, :meth:`angle`)
        [-]: the factor of 3κ in the span's mean slope."""
        return self._m2_grid(np.array([kappa]))[0]

    def _m2_grid(self, kappas: np.ndarray) -> np.ndarray:
        """:meth:`_m2` for each of ``kappas``: (len(kappas), dithers) [-]."""
        span = np.asarray(self._span, dtype=float).reshape(1, -1, 2)
        ends = self._angles(span, np.asarray(kappas, dtype=float)[:, None, None]) / self.theta_s
        lo, hi = ends.min(axis=2), ends.max(axis=2)
        cl, ch = np.maximum(lo, -1.0), np.minimum(hi, 1.0)
        inside = np.where(ch > cl, (ch**3 - cl**3) / 3.0, 0.0)
        point = np.where(np.abs(lo) <= 1.0, lo * lo, 0.0)  # a span of no length
        width = hi - lo
        return np.where(width > 1e-12, inside / np.where(width > 1e-12, width, 1.0), point)

    def _angles(self, readings: np.ndarray, k: np.ndarray | float) -> np.ndarray:
        """:meth:`angle` of readings [rad] for cubics ``k`` (broadcast against each other):
        Newton on the monotone cubic from its first-order root, to rounding for |k| ≤ 0.3."""
        r = np.asarray(readings, dtype=float)
        k = np.asarray(k, dtype=float)
        s = self.theta_s
        th = r / (1.0 + k * (r / s) ** 2)
        for _ in range(6):
            th = th - (th + k * th**3 / s**2 - r) / (1.0 + 3.0 * k * th**2 / s**2)
        beyond = np.abs(r) >= np.abs(s * (1.0 + k))
        return np.where(beyond, r - k * s * np.sign(r), th)

    def estimate(self) -> tuple[float, float, bool]:
        """(κ̂, its standard error, decided): the weighted least-squares fit of
        g = a·(1 + 3κ·m²(κ)) (module docstring)."""
        if self._fit is None:
            self._fit = self._solve()
        return self._fit

    def _profile(self, g: np.ndarray, w: np.ndarray) -> float:
        """κ [-] of the least weighted squares of g − a·(1 + 3κ·m²(κ)), a fitted at each κ
        (a profile over [−0.3, 0.3] on grids refined about their best, to 10⁻⁴: the spans
        are read through the κ tried, so there is no fixed point to land beside, as where
        a span crosses the cubic's clip)."""
        centre = 0.0
        for half, points in ((0.3, 121), (0.005, 21), (0.0005, 11)):
            grid = np.clip(centre + np.linspace(-half, half, points), -0.3, 0.3)
            h = 1.0 + 3.0 * grid[:, None] * self._m2_grid(grid)
            a = (h * (w * g)).sum(axis=1) / (h * h * w).sum(axis=1)
            cost = (w * (g - a[:, None] * h) ** 2).sum(axis=1)
            centre = float(grid[int(np.argmin(cost))])
        return centre

    def _solve(self) -> tuple[float, float, bool]:
        n = len(self._g)
        if n < 2:
            return 0.0, math.inf, False
        enough = n >= MIN_READ  # (the scatter then has MIN_READ − 2 degrees of freedom)
        g = np.asarray(self._g)
        if float(np.std(self._m2(0.0))) < SPREAD_MIN:
            return 0.0, math.inf, False
        # per-dither variance: the expected noise's, and not under REL_FLOOR's; then (a
        # second pass) not under the scatter about the first pass's fit
        var = np.maximum(np.asarray(self._sd) ** 2, (REL_FLOOR * float(np.mean(g))) ** 2)
        for _ in range(2):
            kappa = self._profile(g, 1.0 / var)
            x = np.column_stack([np.ones(n), self._m2(kappa)])
            w = 1.0 / var
            xtwx = x.T @ (x * w[:, None])
            coef = np.linalg.solve(xtwx, x.T @ (w * g))
            a, b = (float(c) for c in coef)
            if a <= 0.0:
                return 0.0, math.inf, False
            res = g - x @ coef
            scatter = float(res @ res) / (n - 2) if n > 2 else 0.0
            var = np.maximum(np.maximum(np.asarray(self._sd) ** 2, scatter), (REL_FLOOR * a) ** 2)
        w = 1.0 / var
        x = np.column_stack([np.ones(n), self._m2(kappa)])
        xtwx = x.T @ (x * w[:, None])
        cov = np.linalg.inv(xtwx)
        a, b = (float(c) for c in np.linalg.solve(xtwx, x.T @ (w * g)))
        if a <= 0.0:
            return 0.0, math.inf, False
        self._gain = a
        grad = np.array([-b / (3.0 * a * a), 1.0 / (3.0 * a)])  # the delta method
        sd = float(np.sqrt(max(grad @ cov @ grad, 0.0)))
        decided = enough and KAPPA_MIN <= abs(kappa) < 1.0 / 3.0 and abs(kappa) >= Z_MIN * sd
        return kappa, sd, decided

    @property
    def kappa(self) -> float:
        """κ̂ where decided, else 0 [-]."""
        k, _sd, ok = self.estimate()
        return k if ok else 0.0

    @property
    def scan_gain(self) -> float | None:
        """K̂, the fit's slope of the reading per offset volt at the centre [rad/V], where κ̂
        is decided (the a of g = a·(1 + 3κ·m²)); None otherwise."""
        ok = self.estimate()[2]
        return self._gain if ok else None

    def reading(self, theta: float) -> float:
        """The reading [rad] of table angle ``theta`` [rad] through the decided cubic,
        θ + κ̂·θ_c³/θ_s² (θ_c clipped to ±θ_s; θ itself while κ̂ is undecided)."""
        tc = min(max(theta, -self.theta_s), self.theta_s)
        return theta + self.kappa * tc**3 / self.theta_s**2

    def table_angle(self, reading: float) -> float:
        """The table angle [rad] behind an unsaturated ``reading`` [rad]: the root of
        θ + κ̂·θ_c³/θ_s² = reading (θ_c = θ clipped to ±θ_s, monotone for |κ| < 1/3);
        the reading itself while κ̂ is undecided."""
        return self.angle(reading, self.kappa)

    def angle(self, reading: float, k: float) -> float:
        """The root θ [rad] of θ + k·θ_c³/θ_s² = ``reading`` [rad] for a cubic of ``k``
        (:meth:`table_angle` with κ̂ where decided)."""
        if k == 0.0:
            return reading
        s = self.theta_s
        edge = s * (1.0 + k)  # the reading at θ = θ_s
        if abs(reading) >= abs(edge):  # beyond the cubic's range: a constant shift
            return reading - k * s * math.copysign(1.0, reading)
        th = reading
        for _ in range(60):  # Newton on a monotone cubic, from θ = r, to rounding
            step = (th + k * th**3 / s**2 - reading) / (1.0 + 3.0 * k * th**2 / s**2)
            th -= step
            if abs(step) <= 1e-15 * s:
                break
        return th
