"""The plane, its contact law, the sensor's latency and low-pass, and friction, from the
samples in contact (SPEC §21; the package's docstring has the model)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt
from scipy import optimize, stats

from admit_rs.identification.findings import Findings
from admit_rs.identification.least_squares import (
    Array,
    LinearFit,
    ResidualFit,
    alpha_of,
    ar1_inflation,
    least_squares,
    low_pass_delay,
    residual_fit,
)
from admit_rs.identification.log_arrays import LogArrays
from admit_rs.identification.model import friction_direction, normal_force

Fit = TypeVar("Fit", LinearFit, ResidualFit)

MAX_LATENCY = 0.05
"""The longest latency searched [s]."""
MOVED = 1e-3
"""The standard deviation of the tip's path along a tangent direction [m] above which the
contact law fixes the normal's tilt towards it."""
SLIDING = 10.0
"""A contact sample slides when |v_t| > SLIDING · v_s."""


@dataclass
class Law:
    """A contact law linear in its coefficients once the touching set is fixed: ``columns``
    gives its regressors (before the sensor's filter) for a touching mask, ``force`` the
    model force of coefficients (positive where touching)."""

    columns: Callable[[Array], Array]
    force: Callable[[Array], Array]


@dataclass
class Search:
    """The contact law's fit at the latency and cut-off of least residual."""

    fit: LinearFit
    touching: npt.NDArray[np.bool_]
    latency: int
    cutoff: float | None
    accepted: list[int]
    cutoff_interval: tuple[float, float] | None
    max_latency: int
    law_interval: tuple[Array, Array]
    """Per coefficient, the union of the (1 − confidence) intervals over the accepted
    (latency, cut-off) pairs."""
    admitted: list[tuple[int, float | None, LinearFit]]
    """The (latency, cut-off, law fit) triples the profile admits."""


class ContactFit:
    """Fits the contact samples of ``cell`` into ``found`` (a plane)."""

    paths: tuple[str, ...] = ("wall.stiffness", "wall.damping", "wall.position", "wall.normal",
                              "sensor.latency", "sensor.cutoff")  # fmt: skip
    """What the contact fit finds besides friction (unidentified without contact)."""

    def __init__(self, cell: LogArrays, found: Findings, stiction: float) -> None:
        self.cell = cell
        self.found = found
        self.stiction = stiction

    def run(self, free: npt.NDArray[np.bool_], static: Array) -> None:
        cell = self.cell
        world = cell.to_world(cell.reading - static)  # the surface's force, as read
        contact = ~free
        normal = self.normal(world, contact)
        window = self.fit_window(contact)
        # Up to three passes: each corrects n where the tip moved along the surface (a tilt ε
        # of n shows as k ε·X in the law) and fits again about the corrected n; the values
        # kept are the last fit's, about the normal reported.
        for attempt in range(3):
            law, tangents = self.kelvin_voigt(normal, contact)
            search = self.law_search(world @ normal, law, contact, window)
            k = search.fit.coef[0]
            tilt = [(t, search.fit.coef[3 + i]) for i, t in enumerate(tangents)]
            if k <= 0 or not tilt or attempt == 2:
                break
            corrected = normal + sum(beta / k * t for t, beta in tilt)
            corrected /= np.linalg.norm(corrected)
            if float(corrected @ normal) > math.cos(math.radians(1e-4)):
                break  # the tilt left is below 1e-4°: the fit about ``normal`` stands
            normal = corrected
        k, kx = search.fit.coef[:2]
        if k <= 0:
            for path in ("wall.stiffness", "wall.damping", "wall.position", "sensor.latency",
                         "sensor.cutoff", "wall.friction"):  # fmt: skip
                self.found.unidentified[path] = (
                    "the force read in contact does not grow with the penetration along the "
                    "fitted normal (no stiffness > 0 fits)"
                )
            return
        self.found.touching = search.touching
        excited = ", tilted by the law where the tip moved along the surface" if tangents else ""
        # The interval: a tilt half-width per tangent direction, from the law where the tip
        # moved along it (the tilt's coefficient), else from the force directions' spread.
        q = self.found.t_quantile(search.fit.dof)
        widths = [(t, math.sqrt(max(float(search.fit.cov[3 + i, 3 + i]), 0.0)) / k * q)
                  for i, t in enumerate(tangents)]  # fmt: skip
        basis = np.linalg.svd(np.eye(3) - np.outer(normal, normal))[0][:, :2].T
        if len(widths) == 1:
            basis = np.array([np.cross(normal, widths[0][0])])
        elif len(widths) == 2:
            basis = np.empty((0, 3))
        widths += [(u, self.tilt_half_width(world, contact, u)) for u in basis]
        half = np.sqrt(sum((t * w) ** 2 for t, w in widths))
        self.found.put("wall.normal", tuple(float(v) for v in normal),
                 tuple((float(v - e), float(v + e)) for v, e in zip(normal, half, strict=True)),
                 "the mean direction of the force read in contact, its part along the "
                 f"velocity (friction) taken out{excited}")  # fmt: skip
        # The bias's interval shifts every normal force read alike: by |its part along n|,
        # which the law reads as a shift of x_e by that over k.
        half = np.array([(b - a) / 2 for a, b in self.found.intervals["sensor.bias"]])
        rotation = cell.rotation[contact].mean(axis=0) if cell.tip_frame else np.eye(3)
        shift = float(np.abs(rotation.T @ normal) @ half) / k
        p_lo, p_hi = self.ratio_interval(search, 0.0, 1)
        self.put_offset(float(kx / k), (p_lo - shift, p_hi + shift),
                        "the contact law's offset: n·X where the force vanishes; the interval "
                        "includes the bias's")  # fmt: skip
        self.put_law(search, world @ normal, window, "δ = n·X − x_e")
        self.hunt_crossley(world @ normal, (cell.x @ normal, cell.v @ normal), contact, window,
                           search)  # fmt: skip
        latency, cutoff = self.found.values["sensor.latency"], self.found.values["sensor.cutoff"]
        normals = np.broadcast_to(normal, cell.x.shape)
        self.friction(static, normals, contact, latency, alpha_of(cutoff, cell.period))

    def put_law(self, search: Search, s: Array, window: npt.NDArray[np.bool_],
                penetration: str) -> None:  # fmt: skip
        """Kelvin–Voigt's stiffness and damping from the law's search (``penetration`` says
        what δ is), the sensor's latency and cut-off, the residual and the contact level of
        ``s``, the normal force read."""
        lo, hi = search.law_interval
        k, c = search.fit.coef[0], search.fit.coef[2]
        samples = int(search.touching.sum())
        self.found.put("wall.stiffness", float(k), (float(lo[0]), float(hi[0])),
                       f"contact ({samples} samples): least squares on f = k δ + c δ̇, "
                       f"{penetration}, passed through the sensor's low-pass and "
                       "latency")  # fmt: skip
        self.found.put("wall.damping", float(c), (float(lo[2]), float(hi[2])),
                       "with the stiffness, the same fit; its interval spans every latency and "
                       "cut-off the log admits (they trade off with the damping)")  # fmt: skip
        self.found.put("wall.model", "kelvin_voigt", None, "Kelvin–Voigt")
        self.put_sensor_dynamics(search)
        self.found.residual_std["contact normal force [N]"] = float(np.std(search.fit.residuals))
        touched = search.touching & window
        if touched.any():
            self.found.contact_level = float(np.median(s[touched]))

    def put_offset(self, offset: float, interval: tuple[float, float], how: str) -> None:
        """The law's offset x_e (where the force vanishes along the coordinate): a plane's
        position."""
        self.found.put("wall.position", offset, interval, how)

    def put_sensor_dynamics(self, search: Search) -> None:
        accepted = (min(search.accepted), max(search.accepted))
        self.found.put("sensor.latency", search.latency, accepted,
                 f"the least residual of the contact fit over 0–{search.max_latency} samples; "
                 "the interval: every latency an F-test does not reject")  # fmt: skip
        if search.cutoff is None:
            self.found.put("sensor.cutoff", None, search.cutoff_interval,
                     "no low-pass fits better than none (the contact fit's residual)")  # fmt: skip
        else:
            self.found.put("sensor.cutoff", search.cutoff, search.cutoff_interval,
                     "the least residual of the contact fit (a bounded search on log "
                     "f_c)")  # fmt: skip

    def ratio_interval(self, search: Search, about: float, index: int) -> tuple[float, float]:
        """The interval of ``about`` + coef[index]/coef[0] (x_e, or a shift of p: delta
        method) united over the admitted fits."""
        q = self.found.t_quantile(search.fit.dof)
        lo, hi = math.inf, -math.inf
        for _, _, f in search.admitted:
            k, b = f.coef[0], f.coef[index]
            if k <= 0:
                return (-math.inf, math.inf)
            grad = np.zeros(len(f.coef))
            grad[0], grad[index] = -b / k**2, 1 / k
            e = math.sqrt(max(float(grad @ f.cov @ grad), 0.0)) * q
            lo, hi = min(lo, about + b / k - e), max(hi, about + b / k + e)
        return (float(lo), float(hi))

    def kelvin_voigt(
        self, normal: Array, contact: npt.NDArray[np.bool_]
    ) -> tuple[Law, list[Array]]:
        """f = k n·X − k x_e + c n·Ẋ (+ k ε_i t_i·X for each tangent t_i the tip moved along:
        a tilt ε of n towards it), and those tangents."""
        cell = self.cell
        depth, rate = cell.x @ normal, cell.v @ normal
        # Tangent directions the tip moved along in contact (the principal directions of its
        # path in the plane, where it spans more than 1 mm).
        path = cell.x[contact] - cell.x[contact].mean(axis=0)
        path = path - np.outer(path @ normal, normal)
        _, spread, directions = np.linalg.svd(path, full_matrices=False)
        spread = spread / math.sqrt(len(path))
        tangents = [directions[i] for i in range(2) if spread[i] > MOVED]
        extra = [cell.x @ t - float(np.mean(cell.x[contact] @ t)) for t in tangents]

        def columns(ind: Array) -> Array:
            return np.column_stack([ind * depth, -ind, ind * rate, *(ind * e for e in extra)])

        def force(coef: Array) -> Array:
            return coef[0] * depth - coef[1] + coef[2] * rate + sum(
                (b * e for b, e in zip(coef[3:], extra, strict=True)), np.zeros_like(depth))

        return Law(columns, force), tangents

    def hunt_crossley_about(self, coordinate: tuple[Array, Array], exponent: float,
                            position: float) -> Law:  # fmt: skip
        """f = k δ^p + c δ^p δ̇ linearised in x_e and p about ``position`` and ``exponent``:
        regressors δ₀^p, δ₀^p δ̇, −p δ₀^(p−1) and δ₀^p ln δ₀ for (k, c, k Δx_e, k Δp),
        δ₀ = max(n·X − x_e, 0), so that k's interval carries p's and x_e's."""
        depth, rate = coordinate
        delta = np.maximum(depth - position, 0.0)
        power = delta**exponent
        slope = exponent * delta ** (exponent - 1) if exponent > 1 else (delta > 0).astype(float)
        logs = np.log(delta, out=np.zeros_like(delta), where=delta > 0)

        def columns(ind: Array) -> Array:
            return np.column_stack([ind * power, ind * power * rate, -ind * slope,
                                    ind * power * logs])  # fmt: skip

        def force(coef: Array) -> Array:
            return (coef[0] * power + coef[1] * power * rate - coef[2] * slope  # type: ignore[no-any-return]
                    + coef[3] * power * logs)

        return Law(columns, force)

    def law_search(self, s: Array, law: Law, contact: npt.NDArray[np.bool_],
                   window: npt.NDArray[np.bool_]) -> Search:  # fmt: skip
        """The latency and cut-off of least residual of ``law`` against the normal force as
        read, ``s``; the profile's admitted pairs and the coefficients' intervals."""
        cell = self.cell
        max_latency = int(round(MAX_LATENCY / cell.period))
        nyquist = 0.5 / cell.period

        def at(latency: int, cutoff: float | None) -> tuple[LinearFit, Any]:
            return self.law_fit(s, law, contact, latency, alpha_of(cutoff, cell.period), window)

        def residual_at(latency: int, cutoff: float | None) -> float:
            alpha = alpha_of(cutoff, cell.period)
            fit, _ = self.touching_fit(s, law, contact, latency, alpha, window, residual_fit)
            return fit.rss

        profile: dict[int, tuple[float, float | None]] = {}
        for latency in range(max_latency + 1):
            result = optimize.minimize_scalar(
                lambda lf, lat=latency: residual_at(lat, math.exp(lf)),
                bounds=(math.log(0.5), math.log(nyquist)), method="bounded",
                options={"xatol": 1e-3},
            )
            cutoff: float | None = float(math.exp(result.x))
            rss = float(result.fun)
            rss_none = residual_at(latency, None)
            if rss_none <= rss:
                cutoff, rss = None, rss_none
            profile[latency] = (rss, cutoff)
        latency = min(profile, key=lambda L: profile[L][0])
        rss, cutoff = profile[latency]
        fit, touching = at(latency, cutoff)
        # Profile intervals: every (latency, cut-off) an F-test at the confidence level does
        # not reject. Latency, cut-off and damping trade off (each a lag or a lead of the
        # force), so the law's own intervals are the union over that set, not conditional on
        # the best pair.
        dof = max(fit.dof, 1.0)
        # Two parameters profiled together: the joint region's F(2, ν).
        threshold = rss * (1 + 2 * stats.f.ppf(self.found.confidence, 2, dof) / dof)
        accepted = [L for L, (r, _) in profile.items() if r <= threshold]
        q = self.found.t_quantile(dof)
        law_lo = np.full(len(fit.coef), np.inf)
        law_hi = np.full(len(fit.coef), -np.inf)
        cut_lo, cut_hi, unfiltered = math.inf, -math.inf, False
        admitted: list[tuple[int, float | None, LinearFit]] = []
        for L in accepted:
            fc = profile[L][1]
            fits = [at(L, fc)[0]]
            admitted.append((L, fc, fits[0]))
            if fc is None:
                unfiltered = True
            else:
                grid = np.exp(np.linspace(math.log(fc) - 2.5, math.log(min(fc * 12, nyquist)), 41))
                passed = []
                for i, g in enumerate(grid):
                    trial = at(L, float(g))[0]
                    if trial.rss <= threshold:
                        passed.append(i)
                        fits.append(trial)
                        admitted.append((L, float(g), trial))
                cut_lo, cut_hi = min(cut_lo, fc), max(cut_hi, fc)
                if passed:
                    # Out to the first grid points rejected: the boundary lies between.
                    below, above = max(min(passed) - 1, 0), min(max(passed) + 1, len(grid) - 1)
                    cut_lo = min(cut_lo, float(grid[below]))
                    cut_hi = max(cut_hi, float(grid[above]))
            for f in fits:
                err = np.sqrt(np.maximum(np.diag(f.cov), 0.0)) * q
                law_lo = np.minimum(law_lo, f.coef - err)
                law_hi = np.maximum(law_hi, f.coef + err)
        interval = None if cutoff is None and not math.isfinite(cut_lo) else (
            (cut_lo, cut_hi if not unfiltered else nyquist))  # fmt: skip
        return Search(fit, touching, latency, cutoff, accepted, interval, max_latency,
                       (law_lo, law_hi), admitted)

    def fit_window(self, contact: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
        """Contact and the samples around it (where a filtered, delayed force still shows)."""
        pad = max(1, int(round(0.1 / self.cell.period)))
        return np.convolve(contact.astype(float), np.ones(2 * pad + 1), "same") > 0

    def law_fit(self, s: Array, law: Law, contact: npt.NDArray[np.bool_], latency: int,
                alpha: float, window: npt.NDArray[np.bool_],
                ) -> tuple[LinearFit, npt.NDArray[np.bool_]]:  # fmt: skip
        """The coefficients of s ≈ D_L LPF_α[law's regressors on the touching set]: the
        touching set from the previous estimate (starting from the segmentation's
        contact), until it stops changing (ten times at most)."""
        return self.touching_fit(s, law, contact, latency, alpha, window, least_squares)

    @staticmethod
    def touching_fit(
        s: Array, law: Law, contact: npt.NDArray[np.bool_], latency: int, alpha: float,
        window: npt.NDArray[np.bool_], solve: Callable[[Array, Array], Fit],
    ) -> tuple[Fit, npt.NDArray[np.bool_]]:
        """:meth:`law_fit` with the solver ``solve`` (``least_squares``, or ``residual_fit``
        where only the residual is wanted)."""
        touching = contact
        fit = None
        for _ in range(10):
            design = low_pass_delay(law.columns(touching.astype(float)), alpha, latency)
            fit = solve(design[window], s[window])
            if fit.coef[0] <= 0:
                break
            new = law.force(fit.coef) > 0
            if np.array_equal(new, touching):
                break
            touching = new
        assert fit is not None
        return fit, touching

    def normal(self, world: Array, contact: npt.NDArray[np.bool_]) -> Array:
        """n̂: the mean force direction in contact with its part along the tip's velocity
        taken out (friction acts along v_t, the normal force along n)."""
        normal_part, _ = self.normal_parts(world, contact)
        n = np.sum(normal_part, axis=0)
        return np.asarray(n / np.linalg.norm(n), dtype=float)

    def normal_parts(
        self, world: Array, contact: npt.NDArray[np.bool_]
    ) -> tuple[Array, npt.NDArray[np.intp]]:
        """The force read in contact with friction taken out, where the model says how:
        sliding (|v| > SLIDING v_s), the tip's velocity is tangential and the force's part
        along it is friction; still (|v| < v_s/10), friction (μ f |v_t|/√(|v_t|² + v_s²))
        is below a tenth of μ f and the force is kept. Samples in between (an impact, a
        creep at about v_s, where the velocity has a normal part and friction is large) say
        little about n and are left out, unless nothing else is left. Also the samples'
        indices."""
        f = world[contact]
        v = self.cell.v[contact]
        speed = np.linalg.norm(v, axis=1, keepdims=True)
        vs = self.stiction
        sliding = speed[:, 0] > SLIDING * vs
        still = speed[:, 0] < 0.1 * vs
        keep = sliding | still
        if keep.sum() < 20:
            keep = np.ones(len(f), dtype=bool)
        moving = (speed > 1e-12) & ~still[:, None]
        direction = np.divide(v, speed, out=np.zeros_like(v), where=moving)
        parts = f - np.sum(f * direction, axis=1, keepdims=True) * direction
        return parts[keep], np.flatnonzero(contact)[keep]

    def tilt_half_width(self, world: Array, contact: npt.NDArray[np.bool_], u: Array) -> float:
        """The half-width of n̂'s tilt towards the tangent ``u`` [rad] from the spread of the
        force directions (those of at least a fifth of the median force)."""
        parts, _ = self.normal_parts(world, contact)
        size = np.linalg.norm(parts, axis=1)
        keep = size > 0.2 * float(np.median(size))
        tilt = parts[keep] @ u / size[keep]
        inflation, _ = ar1_inflation(tilt)
        n_eff = max(len(tilt) / inflation, 3.0)
        spread = float(np.std(tilt)) / math.sqrt(n_eff) * self.found.t_quantile(n_eff - 1)
        # The bias's own interval tilts every reading alike: |its part along u| / |f|.
        half = np.array([(hi - lo) / 2 for lo, hi in self.found.intervals["sensor.bias"]])
        rotation = self.cell.rotation[contact].mean(axis=0) if self.cell.tip_frame else np.eye(3)
        bias = float(np.abs(rotation.T @ u) @ half) / float(np.median(size))
        return spread + bias

    def hunt_crossley(self, s: Array, coordinate: tuple[Array, Array],
                      contact: npt.NDArray[np.bool_], window: npt.NDArray[np.bool_],
                      kv: Search) -> None:  # fmt: skip
        """Hunt–Crossley, f = k δ^p + c δ^p δ̇: p and x_e by nonlinear least squares at the
        best latency and cut-off, then the latency and cut-off searched again with the law
        linearised about them (k, c and x_e's shift are linear there), twice. Kept only if an
        F-test prefers it to Kelvin–Voigt. Intervals from the linearised fits, united over
        the latencies and cut-offs the log admits."""
        cell = self.cell
        depth, rate = coordinate
        k0, kx0, c0 = kv.fit.coef[:3]
        period = cell.period

        def nonlinear(lat: int, fc: float | None, start: Array) -> Any:
            alpha = alpha_of(fc, period)

            def residual(p: Array) -> Array:
                k, tau, exponent, xe = math.exp(p[0]), p[1], p[2], p[3]
                law = normal_force(depth - xe, rate, k, k * tau, exponent)
                return (low_pass_delay(law, alpha, lat) - s)[window]  # type: ignore[no-any-return]

            try:
                return optimize.least_squares(residual, start, method="trf", x_scale="jac",
                                              bounds=([-np.inf, -np.inf, 1.0, -np.inf],
                                                      [np.inf, np.inf, 10.0, np.inf]))  # fmt: skip
            except (ValueError, np.linalg.LinAlgError):
                return None

        start = np.array([math.log(k0), c0 / k0, 1.0, kx0 / k0])
        sol = nonlinear(kv.latency, kv.cutoff, start)
        if sol is None:
            return
        search = kv
        for _ in range(2):
            exponent, position = float(sol.x[2]), float(sol.x[3])
            search = self.law_search(s, self.hunt_crossley_about(coordinate, exponent,
                                                                 position),
                                     contact, window)  # fmt: skip
            if search.fit.coef[0] <= 0:
                return
            better = nonlinear(search.latency, search.cutoff, sol.x)
            if better is None:
                return
            sol = better
        rss_hc = float(sol.fun @ sol.fun)
        dof = max(kv.fit.dof - 1, 1)
        f_stat = (kv.fit.rss - rss_hc) / (rss_hc / dof) if rss_hc > 0 else math.inf
        if f_stat <= stats.f.ppf(self.found.confidence, 1, dof):
            self.found.how["wall.model"] = (
                f"Kelvin–Voigt: Hunt–Crossley (p = {sol.x[2]:.3g}) does not fit significantly "
                f"better (F = {f_stat:.3g} against the {100 * self.found.confidence:.0f} % level)"
            )
            return
        lo, hi = search.law_interval
        how = (f"contact: f = k δ^p + c δ^p δ̇ through the sensor's low-pass and latency, "
               f"preferred to Kelvin–Voigt by an F-test (F = {f_stat:.3g}); k, c over every "
               f"latency and cut-off the log admits")  # fmt: skip
        k = math.exp(float(sol.x[0]))
        self.found.put("wall.model", "hunt_crossley", None, how)
        self.found.put("wall.stiffness", k, (float(lo[0]), float(hi[0])), how)
        self.found.put("wall.damping", k * float(sol.x[1]), (float(lo[1]), float(hi[1])), how)
        p_lo, p_hi = self.ratio_interval(search, exponent, 3)
        self.found.put("wall.exponent", float(sol.x[2]), (max(p_lo, 1.0), p_hi), how)
        self.put_offset(float(sol.x[3]), self.ratio_interval(search, position, 2), how)
        self.put_sensor_dynamics(search)
        self.found.touching = search.touching
        self.found.residual_std["contact normal force [N]"] = math.sqrt(rss_hc / len(sol.fun))

    def friction(self, static: Array, normals: Array, contact: npt.NDArray[np.bool_],
                 latency: int, alpha: float) -> None:  # fmt: skip
        """μ from the ratio of the tangential to the normal force as read, where the tip slid
        steadily one way (both pass through the same low-pass, so their ratio is μ |g|
        there, g = v_t/√(|v_t|² + v_s²)); the interval adds the bias's own interval."""
        vs = self.stiction
        v = self.cell.v
        speed = np.linalg.norm(v - np.sum(v * normals, axis=1, keepdims=True) * normals, axis=1)
        sliding = contact & (speed > SLIDING * vs)
        g = friction_direction(v, normals, vs)
        # Steady: sliding, in the same direction (g within 10°), for the filter's settling
        # time (five time constants) plus the latency.
        settle = latency + int(math.ceil(5 / max(alpha, 1e-9)))
        heading = np.ones(len(g), dtype=bool)
        for lag in range(1, settle + 1):
            same = np.sum(g[lag:] * g[:-lag], axis=1) > math.cos(math.radians(10)) * np.sum(
                g[lag:] ** 2, axis=1)  # fmt: skip
            heading[lag:] &= same & sliding[:-lag]
            heading[:lag] = False
        steady = sliding & heading
        if steady.sum() < max(20, 0.05 * contact.sum()):
            self.found.unidentified["wall.friction"] = (
                f"the tool did not slide steadily ({int(steady.sum())} contact samples moving "
                f"one way faster than {SLIDING * vs:g} m/s for {settle} samples or more)"
            )
            return

        def fit_mu(static_: Array) -> tuple[float, float]:
            world = self.cell.to_world(self.cell.reading - static_)
            normal_force = np.sum(world * normals, axis=1)
            tangential = world - normal_force[:, None] * normals
            regressor = (normal_force[:, None] * g)[steady]
            lsq = least_squares(regressor.reshape(-1, 1), tangential[steady].reshape(-1),
                                 columns=3)  # fmt: skip
            err = math.sqrt(max(float(lsq.cov[0, 0]), 0.0)) * self.found.t_quantile(lsq.dof)
            return float(lsq.coef[0]), err

        mu, err = fit_mu(static)
        # The bias is off on every axis at once: its corners move μ by the sum of what each
        # axis's interval does (one axis at a time, the union, covered 6 of 8 seeds of a
        # sphere; the sum, all).
        below = above = 0.0
        for axis, (b_lo, b_hi) in enumerate(self.found.intervals["sensor.bias"]):
            moves = []
            for end in (b_lo, b_hi):
                shifted = static.copy()
                shifted[:, axis] += end - self.found.values["sensor.bias"][axis]
                moves.append(fit_mu(shifted)[0] - mu)
            below += max(0.0, -min(moves))
            above += max(0.0, max(moves))
        lo, hi = mu - err - below, mu + err + above
        self.found.put("wall.friction", mu, (lo, hi),
                 f"steady sliding ({int(steady.sum())} samples): least squares of the "
                 f"tangential force read on f v_t/√(|v_t|² + v_s²), f the normal force read, "
                 f"v_s = {vs:g} m/s; the interval includes the bias's (its corners)")  # fmt: skip
